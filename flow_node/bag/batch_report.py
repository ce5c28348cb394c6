"""The batch report of ``flow_bag eval`` over many bags: report.json, report.md, aee_per_bag.png and
time_per_frame.png in the batch's output folder.

Built from each bag's own report.json (as :func:`flow_node.bag.batch.evaluate_bag` returns it), so a bag
skipped from the cache counts exactly as when it was evaluated. Per bag and model: frames, pairs, AEE/AE
where ground truth exists, magnitude statistics, solve time. Per model: aggregates over the bags. Across
bags, with several models: the paper's Table 1 ranking, bag by bag (each bag's mean AEE over the smallest
mean AEE of that bag, averaged over the bags every model scored).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..core.config import FlowConfig
from . import plots
from .report import fmt, ratio_ranking
from .results import BATCH_FORMAT, BagOutcome

PNGS = ("aee_per_bag.png", "time_per_frame.png")


def _num(x: Any) -> float | None:
    """A finite float, or None (missing, NaN, inf)."""
    return float(x) if isinstance(x, int | float) and math.isfinite(float(x)) else None


def _stat(values: Sequence[Any], fn: Any) -> float | None:
    clean = plots.finite(values)
    return float(fn(clean)) if clean else None


def bag_rows(outcomes: Sequence[BagOutcome]) -> list[dict[str, Any]]:
    """One row per bag and model (one row for a failed bag): the bag's summary numbers."""
    rows = []
    for o in outcomes:
        base = {"bag": o.name, "path": o.bag, "status": o.status, "reason": o.reason, "task_seconds": o.seconds,
                "host": o.host, "pid": o.pid}
        if o.report is None:
            rows.append(base | {"model": None})
            continue
        for m in o.report["models"]:
            s = m["summary"]
            rows.append(base | {
                "model": m["label"], "frames": o.report["images"], "pairs": s["pairs"],
                "pairs_with_gt": s["pairs_with_gt"], "aee_mean": _num(s["aee_mean"]), "ae_mean": _num(s["ae_mean"]),
                "magnitude_mean": _num(s["magnitude_mean"]), "magnitude_max": _num(s["magnitude_max"]),
                "seconds_mean": _num(s["seconds_mean"]),
                "frame_seconds": [_num(f["seconds"]) for f in m["frames"] if f["seconds"] is not None]})
    return rows


def aggregates(rows: Sequence[dict[str, Any]], labels: Sequence[str]) -> list[dict[str, Any]]:
    """Per model: bags, bags with ground truth, pairs; mean and median over bags of the per-bag AEE, mean
    AE, mean |flow|; solve time per frame (median, 95th percentile, mean) pooled over all frames."""
    out = []
    for label in labels:
        mine = [r for r in rows if r["model"] == label]
        scored = [r for r in mine if r["aee_mean"] is not None]
        secs = [t for r in mine for t in r["frame_seconds"]]
        out.append({
            "model": label, "bags": len(mine), "bags_with_gt": len(scored), "pairs": sum(r["pairs"] for r in mine),
            "aee_mean_over_bags": _stat([r["aee_mean"] for r in scored], np.mean),
            "aee_median_over_bags": _stat([r["aee_mean"] for r in scored], np.median),
            "ae_mean_over_bags": _stat([r["ae_mean"] for r in scored], np.mean),
            "magnitude_mean_over_bags": _stat([r["magnitude_mean"] for r in mine], np.mean),
            "seconds_per_frame_median": _stat(secs, np.median),
            "seconds_per_frame_p95": _stat(secs, lambda v: np.percentile(v, 95)),
            "seconds_per_frame_mean": _stat(secs, np.mean)})
    return out


def bag_ranking(rows: Sequence[dict[str, Any]], labels: Sequence[str]) -> list[dict[str, Any]]:
    """The paper's ranking with bags as the items: per bag, each model's mean AEE (AE) over the best."""
    scores: dict[str, dict[str, tuple[float, float]]] = {}
    for r in rows:
        if r["model"] is not None and r["aee_mean"] is not None and r["ae_mean"] is not None:
            scores.setdefault(r["bag"], {})[r["model"]] = (r["aee_mean"], r["ae_mean"])
    return ratio_ranking(scores, labels, count_key="bags")


def draw(rows: Sequence[dict[str, Any]], labels: Sequence[str], folder: Path) -> None:
    """aee_per_bag.png (grouped bars, n/a without ground truth) and time_per_frame.png (histograms)."""
    bags = list(dict.fromkeys(r["bag"] for r in rows if r["model"] is not None))  # failed bags: in the table
    value = {(r["bag"], r["model"]): r["aee_mean"] for r in rows if r["model"] is not None}
    fig, (ax,) = plots.new_figure(1, width=max(7.2, 0.5 * len(bags) * max(len(labels), 1) + 2), row_height=3.6)
    plots.bar_panel(ax, bags, {m: [value.get((b, m)) for b in bags] for m in labels}, "AEE per bag (mean over "
                    "its frames)", "AEE (px)")
    plots.save(fig, folder / PNGS[0])
    ms = {m: [1000 * t for r in rows if r["model"] == m for t in r["frame_seconds"]] for m in labels}
    fig, (ax,) = plots.new_figure(1, row_height=3.2)
    plots.histogram_panel(ax, ms, "solve time per frame, all bags", "time (ms)")
    plots.save(fig, folder / PNGS[1])


def to_markdown(data: dict[str, Any]) -> str:
    """report.md: counts, per-bag table, aggregates, ranking, failures, pictures."""
    c = data["counts"]
    lines = ["# flow_bag eval: batch", "",
             f"{c['bags']} bags on {data['scheduler']}: {c['done']} evaluated, {c['skipped']} skipped (cached), "
             f"{c['failed']} failed; {data['wall_seconds']:.1f} s wall, {fmt(data['bags_per_minute'], 1)} bags "
             "evaluated per minute. AEE in px, AE in degrees (Middlebury), |flow| in px, times in ms per frame "
             "pair. Each bag's own report is `bags/<bag>/report.md`.", "", "## Bags", "",
             "| bag | status | model | frames | pairs | with GT | AEE | AE | mean \\|flow\\| | max \\|flow\\| "
             "| time mean | note |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in data["bags"]:
        if r["model"] is None:
            lines.append(f"| {r['bag']} | {r['status']} | – | – | – | – | – | – | – | – | – | {r['reason']} |")
            continue
        ms = None if r["seconds_mean"] is None else 1000 * r["seconds_mean"]
        lines.append(f"| {r['bag']} | {r['status']} | {r['model']} | {r['frames']} | {r['pairs']} | "
                     f"{r['pairs_with_gt']} | {fmt(r['aee_mean'])} | {fmt(r['ae_mean'], 2)} | "
                     f"{fmt(r['magnitude_mean'])} | {fmt(r['magnitude_max'])} | {fmt(ms, 1)} | |")
    lines += ["", "## Per model", "", "| model | bags | with GT | pairs | AEE mean | AEE median | AE mean "
              "| mean \\|flow\\| | time median | time p95 |", "|---|---|---|---|---|---|---|---|---|---|"]
    for a in data["aggregates"]:
        t = {k: None if a[k] is None else 1000 * a[k] for k in ("seconds_per_frame_median", "seconds_per_frame_p95")}
        lines.append(f"| {a['model']} | {a['bags']} | {a['bags_with_gt']} | {a['pairs']} | "
                     f"{fmt(a['aee_mean_over_bags'])} | {fmt(a['aee_median_over_bags'])} | "
                     f"{fmt(a['ae_mean_over_bags'], 2)} | {fmt(a['magnitude_mean_over_bags'])} | "
                     f"{fmt(t['seconds_per_frame_median'], 1)} | {fmt(t['seconds_per_frame_p95'], 1)} |")
    if data["ranking"]:
        lines += ["", "## Ranking across bags (as the paper's Table 1)", "",
                  f"Mean over the {data['ranking'][0]['bags']} bags with ground truth of the bag's AEE / the best "
                  "AEE on that bag (likewise AE); 1 = best on every bag.", "",
                  "| rank | model | ∅ AEE/min AEE | ∅ AE/min AE |", "|---|---|---|---|"]
        lines += [f"| {r['rank']} | {r['model']} | {r['mean_aee_over_min']:.3f} | {r['mean_ae_over_min']:.3f} |"
                  for r in data["ranking"]]
    if data["failures"]:
        lines += ["", "## Failed bags", ""] + [f"- `{f['bag']}`: {f['reason']}" for f in data["failures"]]
    lines += ["", "## Pictures", ""] + [f"![{p}]({p})" for p in PNGS]
    return "\n".join(lines) + "\n"


def write_batch_report(outcomes: Sequence[BagOutcome], folder: Path, configs: Sequence[FlowConfig],
                       wall_seconds: float, scheduler: str) -> dict[str, Any]:
    """Write report.json, report.md and the PNGs into ``folder``; returns the report data."""
    labels = list(dict.fromkeys(c.model for c in configs))
    rows = bag_rows(outcomes)
    counts = {s: sum(o.status == s for o in outcomes) for s in ("done", "skipped", "failed")}
    data = {
        "format": BATCH_FORMAT, "scheduler": scheduler, "wall_seconds": wall_seconds,
        "counts": {"bags": len(outcomes)} | counts,
        "bags_per_minute": 60.0 * counts["done"] / wall_seconds if counts["done"] and wall_seconds > 0 else None,
        "configs": [c.to_dict() for c in configs], "bags": rows, "aggregates": aggregates(rows, labels),
        "ranking": bag_ranking(rows, labels),
        "failures": [{"bag": o.name, "path": o.bag, "reason": o.reason} for o in outcomes if o.status == "failed"],
    }
    draw(rows, labels, folder)
    (folder / "report.json").write_text(json.dumps(data, indent=1) + "\n")
    (folder / "report.md").write_text(to_markdown(data))
    return data
