"""The verdict of `flow_bag eval`: report.json, report.md, per-frame panels (OpenCV tiles of the exact pixels)
and the per-frame plot (matplotlib, :mod:`flow_node.bag.plots`).

Summary per model: AEE/AE (Middlebury definitions) where ground truth exists, solve time, magnitude
statistics. With several models, a ranking as in the paper's Table 1: the mean over frames of
AEE / (smallest AEE of that frame), and the same for AE.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..core.errors import FileFormatError
from ..core.flowio import flow_to_color
from ..core.metrics import endpoint_error_map
from . import plots
from .results import Drawn, EvalResult, ModelRun


def _stat(values: list[float], fn: Any) -> float | None:
    return float(fn(values)) if values else None


def summarise_run(run: ModelRun) -> dict[str, Any]:
    """Summary numbers of one model run (None where nothing was measured)."""
    pairs = [r for r in run.records if r.seconds is not None]
    scored = [r for r in pairs if r.aee is not None]
    secs = [r.seconds for r in pairs if r.seconds is not None]
    return {
        "model": run.label, "backend": run.stream.backend, "images": len(run.records), "pairs": len(pairs),
        "pairs_with_gt": len(scored),
        "aee_mean": _stat([r.aee for r in scored], np.mean), "aee_median": _stat([r.aee for r in scored], np.median),
        "aee_max": _stat([r.aee for r in scored], np.max), "ae_mean": _stat([r.ae for r in scored], np.mean),
        "confidence_auc_mean": _stat([r.confidence_auc for r in scored if r.confidence_auc is not None], np.mean),
        "seconds_mean": _stat(secs, np.mean), "seconds_median": _stat(secs, np.median),
        "iterations_mean": _stat([r.iterations for r in pairs], np.mean),
        "magnitude_mean": _stat([r.magnitude["mean"] for r in pairs if r.magnitude], np.mean),
        "magnitude_max": _stat([r.magnitude["max"] for r in pairs if r.magnitude], np.max),
        "motion": summarise_motion(run),
    }


def summarise_motion(run: ModelRun) -> dict[str, Any] | None:
    """The derived motion outputs over the run's pairs (``--motion``; None without): pairs, pairs with
    ``motion detected``, mean moving fraction, medians of the dominant inlier share, the central TTC (s)
    and the time all outputs took; with ground truth the medians of their errors against the outputs of
    the ground-truth flow (motion_topics.truth_errors)."""
    rows = [r.motion for r in run.records if r.motion is not None]
    if not rows:
        return None

    def values(key: str, src: list[dict[str, Any]]) -> list[float]:
        return [m[key] for m in src if m.get(key) is not None]

    dominant = [m["dominant"] for m in rows if m["dominant"] is not None]
    out = {"pairs": len(rows), "pairs_detected": sum(bool(m["detected"]) for m in rows),
           "moving_fraction_mean": _stat(values("moving_fraction", rows), np.mean),
           "inlier_share_median": _stat(values("inlier_share", dominant), np.median),
           "ttc_centre_seconds_median": _stat(values("ttc_centre_seconds", rows), np.median),
           "seconds_mean": _stat(values("seconds", rows), np.mean)}
    truth = [m["vs_ground_truth"] for m in rows if "vs_ground_truth" in m]
    for key in ("translation_err_px", "rotation_err_deg", "ttc_centre_rel_err", "mask_iou"):
        out[f"{key}_median"] = _stat(values(key, truth), np.median)
    return out


def ratio_ranking(scores: Mapping[Any, Mapping[str, tuple[float, float]]], labels: Sequence[str],
                  count_key: str = "frames") -> list[dict[str, Any]]:
    """Paper Table 1 style over items (frames of a bag, or bags of a batch) keyed in ``scores`` to
    {label: (AEE, AE)}: per label, the mean over the items scored (finitely) by every label of AEE / min AEE
    and AE / min AE; sorted best first, with ``rank`` and the item count under ``count_key``. Empty with
    fewer than two labels or no common item."""
    if len(labels) < 2:
        return []
    common = [v for v in scores.values()
              if all(k in v and math.isfinite(v[k][0]) and math.isfinite(v[k][1]) for k in labels)]
    if not common:
        return []
    rows = []
    for label in labels:
        q_aee = [v[label][0] / max(min(v[k][0] for k in labels), 1e-12) for v in common]
        q_ae = [v[label][1] / max(min(v[k][1] for k in labels), 1e-12) for v in common]
        rows.append({"model": label, "mean_aee_over_min": float(np.mean(q_aee)),
                     "mean_ae_over_min": float(np.mean(q_ae)), count_key: len(common)})
    rows.sort(key=lambda r: (r["mean_aee_over_min"], r["mean_ae_over_min"]))
    for k, row in enumerate(rows, 1):
        row["rank"] = k
    return rows


def ranking(runs: list[ModelRun]) -> list[dict[str, Any]]:
    """:func:`ratio_ranking` over the frames of one bag."""
    per_frame: dict[int, dict[str, tuple[float, float]]] = {}
    for run in runs:
        for r in run.records:
            if r.aee is not None and r.ae is not None:
                per_frame.setdefault(r.index, {})[run.label] = (r.aee, r.ae)
    return ratio_ranking(per_frame, [run.label for run in runs])


def to_json(result: EvalResult) -> dict[str, Any]:
    """The full report as plain data."""
    return {
        "bag": result.bag, "image_topic": result.image_topic, "gt_topic": result.gt_topic,
        "images": result.images, "color_max_flow": result.color_max_flow,
        "wall_seconds": result.wall_seconds,
        "models": [{"label": run.label, "config": run.config.to_dict(), "summary": summarise_run(run),
                    "frames": [vars(r) for r in run.records]} for run in result.runs],
        "ranking": ranking(result.runs),
        "recovered": result.recovered, "warnings": result.warnings,
    }


def fmt(x: float | None, digits: int = 3) -> str:
    """A number as the reports' tables show it: ``digits`` decimals, a dash for None or NaN."""
    return "–" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{digits}f}"


def to_markdown(result: EvalResult, pngs: list[str]) -> str:
    """report.md: summary, ranking, per-frame tables, pictures."""
    has_gt = any(r.aee is not None for run in result.runs for r in run.records)
    lines = [f"# flow_bag eval: {Path(result.bag).name}", "",
             f"Bag `{result.bag}`, image topic `{result.image_topic}`, ground truth "
             f"{'`' + result.gt_topic + '`' if result.gt_topic else 'none'}; {result.images} images. "
             "AEE in px, AE in degrees (Middlebury definitions), times in ms per frame pair; confidence AUC: "
             "ROC AUC of ~/confidence for 'endpoint error < 3 px or 5 % of |gt|' (1 = perfect, 0.5 = chance).", "",
             "## Summary", "",
             "| model | backend | pairs | with GT | AEE mean | AEE median | AE mean | confidence AUC | time mean "
             "| time median | mean \\|flow\\| |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for run in result.runs:
        s = summarise_run(run)
        ms = {k: None if s[k] is None else 1000 * s[k] for k in ("seconds_mean", "seconds_median")}
        lines.append(f"| {s['model']} | {s['backend']} | {s['pairs']} | {s['pairs_with_gt']} | "
                     f"{fmt(s['aee_mean'])} | {fmt(s['aee_median'])} | {fmt(s['ae_mean'], 2)} | "
                     f"{fmt(s['confidence_auc_mean'])} | {fmt(ms['seconds_mean'], 1)} | "
                     f"{fmt(ms['seconds_median'], 1)} | "
                     f"{fmt(s['magnitude_mean'])} |")
    lines += _motion_markdown(result.runs)
    rank = ranking(result.runs)
    if rank:
        lines += ["", "## Ranking (as the paper's Table 1)", "",
                  f"Mean over the {rank[0]['frames']} frames of AEE / min AEE and AE / min AE (1 = best on "
                  "every frame).", "", "| rank | model | ∅ AEE/min AEE | ∅ AE/min AE |", "|---|---|---|---|"]
        lines += [f"| {r['rank']} | {r['model']} | {r['mean_aee_over_min']:.3f} | {r['mean_ae_over_min']:.3f} |"
                  for r in rank]
    for run in result.runs:
        lines += ["", f"## Frames: {run.label}", ""]
        if has_gt:
            lines += ["| frame | stamp (s) | AEE | AE | time (ms) | iterations | mean \\|flow\\| | note |",
                      "|---|---|---|---|---|---|---|---|"]
        else:
            lines += ["| frame | stamp (s) | time (ms) | iterations | mean \\|flow\\| | p95 | max | note |",
                      "|---|---|---|---|---|---|---|---|"]
        for r in run.records:
            mag = r.magnitude or {}
            ms = None if r.seconds is None else 1000 * r.seconds
            note = r.skipped or r.note or ""
            it = "–" if r.iterations is None else str(r.iterations)
            head = f"| {r.index} | {r.stamp_ns / 1e9:.3f} |"
            if has_gt:
                lines.append(f"{head} {fmt(r.aee)} | {fmt(r.ae, 2)} | {fmt(ms, 1)} | {it} | "
                             f"{fmt(mag.get('mean'))} | {note} |")
            else:
                lines.append(f"{head} {fmt(ms, 1)} | {it} | {fmt(mag.get('mean'))} | {fmt(mag.get('p95'))} | "
                             f"{fmt(mag.get('max'))} | {note} |")
    if pngs:
        lines += ["", "## Pictures", ""] + [f"![{p}]({p})" for p in pngs]
    return "\n".join(lines) + "\n"


def _motion_markdown(runs: list[ModelRun]) -> list[str]:
    """The 'Derived motion' table (``--motion``), or nothing."""
    rows = [(run.label, summarise_motion(run)) for run in runs]
    if all(m is None for _, m in rows):
        return []
    lines = ["", "## Derived motion (--motion)", "",
             "Per model over its pairs: pairs with `motion detected`, mean moving fraction, median inlier share of "
             "the dominant motion, median central time to contact (s), mean time of all derived outputs (ms); "
             "with ground truth, medians of the errors against the same outputs of the ground-truth flow "
             "(translation px, rotation deg, central TTC relative, moving-mask IoU).", "",
             "| model | pairs | detected | moving | inliers | TTC centre (s) | time (ms) | translation | rotation "
             "| TTC rel. | mask IoU |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for label, m in rows:
        if m is not None:
            ms = None if m["seconds_mean"] is None else 1000 * m["seconds_mean"]
            lines.append(f"| {label} | {m['pairs']} | {m['pairs_detected']} | {fmt(m['moving_fraction_mean'])} | "
                         f"{fmt(m['inlier_share_median'])} | {fmt(m['ttc_centre_seconds_median'], 2)} | "
                         f"{fmt(ms, 1)} | {fmt(m['translation_err_px_median'])} | "
                         f"{fmt(m['rotation_err_deg_median'])} | {fmt(m['ttc_centre_rel_err_median'])} | "
                         f"{fmt(m['mask_iou_median'])} |")
    return lines


def summary_lines(result: EvalResult) -> list[str]:
    """A few lines for the terminal."""
    out = []
    for run in result.runs:
        s = summarise_run(run)
        ms = "–" if s["seconds_mean"] is None else f"{1000 * s['seconds_mean']:.1f} ms"
        err = f"AEE {fmt(s['aee_mean'])} px, AE {fmt(s['ae_mean'], 2)} deg, " if s["pairs_with_gt"] else ""
        out.append(f"{run.label}: {s['pairs']} pairs, {err}mean |flow| {fmt(s['magnitude_mean'])} px, "
                   f"{ms} per pair ({s['backend']})")
    return out


# ------------------------------------------------------------------------------------------------ pictures
def _tile(img: np.ndarray, label: str, zoom: int) -> np.ndarray:
    """BGR uint8 tile, enlarged by ``zoom`` (nearest), with a label strip on top."""
    big = cv2.resize(img, (img.shape[1] * zoom, img.shape[0] * zoom), interpolation=cv2.INTER_NEAREST)
    strip = np.full((18, big.shape[1], 3), 255, np.uint8)
    cv2.putText(strip, label, (3, 13), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    return np.vstack([strip, big])


def frame_bgr(frame: np.ndarray) -> np.ndarray:
    """Any decoded frame (grey/RGB, uint8/uint16/float) -> BGR uint8 for display."""
    f = frame.astype(np.float32)
    f = f / 255.0 if frame.dtype == np.uint8 else f / 65535.0 if frame.dtype == np.uint16 else f
    f = np.clip(f * 255.0 + 0.5, 0, 255).astype(np.uint8)
    return cv2.cvtColor(f, cv2.COLOR_GRAY2BGR) if f.ndim == 2 else np.ascontiguousarray(f[..., ::-1])


def error_bgr(flow: np.ndarray, gt: np.ndarray, emax: float) -> np.ndarray:
    """Endpoint error map, 0..emax px on the inferno colour map; unknown ground truth black."""
    err = endpoint_error_map(flow, gt)
    u8 = np.clip(np.nan_to_num(err, nan=0.0) / emax * 255.0, 0, 255).astype(np.uint8)
    out = cv2.applyColorMap(u8, cv2.COLORMAP_INFERNO)
    out[np.isnan(err)] = 0
    return out


def panel(d: Drawn, max_flow: float, emax: float) -> np.ndarray:
    """One row per model: frame, ground-truth colour, flow colour, error map (or magnitude without GT)."""
    zoom = max(1, 320 // d.frame.shape[1])
    rows = []
    for label, flow in d.flows.items():
        tiles = [_tile(frame_bgr(d.frame), f"frame {d.index}", zoom)]
        if d.gt is not None:
            tiles.append(_tile(flow_to_color(d.gt, max_flow, bgr=True), "ground truth", zoom))
        tiles.append(_tile(flow_to_color(flow, max_flow, bgr=True), f"{label} flow", zoom))
        if d.gt is not None:
            tiles.append(_tile(error_bgr(flow, d.gt, emax), f"error 0-{emax:g} px", zoom))
        rows.append(np.hstack(tiles))
    return np.vstack(rows)


def per_frame_plot(result: EvalResult, path: Path) -> None:
    """per_frame.png: AEE per frame (if any ground truth) above solve time per frame (ms), one line per model."""
    aee = {r.label: [(x.index, x.aee) for x in r.records] for r in result.runs}
    ms = {r.label: [(x.index, None if x.seconds is None else 1000 * x.seconds) for x in r.records]
          for r in result.runs}
    has_gt = any(x.aee is not None for r in result.runs for x in r.records)
    fig, axes = plots.new_figure(2 if has_gt else 1)
    if has_gt:
        plots.line_panel(axes[0], aee, "AEE per frame", "frame", "AEE (px)")
    plots.line_panel(axes[-1], ms, "solve time per frame", "frame", "time (ms)")
    plots.save(fig, path)


def _imwrite(path: Path, img: np.ndarray) -> None:
    if not cv2.imwrite(str(path), img):
        raise FileFormatError(f"cannot write {path}")


def write_report(result: EvalResult, folder: Path) -> list[str]:
    """Write report.json, report.md and the PNGs into ``folder``; returns the PNG names."""
    errors = [endpoint_error_map(f, d.gt) for d in result.drawn if d.gt is not None for f in d.flows.values()]
    finite = np.concatenate([e[np.isfinite(e)] for e in errors]) if errors else np.zeros(0)
    emax = max(0.5, math.ceil(2 * float(np.percentile(finite, 99))) / 2) if finite.size else 1.0
    pngs = []
    for d in result.drawn:
        if d.flows:
            name = f"frame_{d.index:04d}.png"
            _imwrite(folder / name, panel(d, result.color_max_flow, emax))
            pngs.append(name)
    per_frame_plot(result, folder / "per_frame.png")
    pngs.append("per_frame.png")
    (folder / "report.json").write_text(json.dumps(to_json(result), indent=1) + "\n")
    (folder / "report.md").write_text(to_markdown(result, pngs))
    return pngs
