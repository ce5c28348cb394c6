"""Large displacements (issue 12): presets x initialisations beside OpenCV DIS, one run, per pair.

    python -m bench.large                                  # ../shared/data/large -> bench/results/large.json
    python -m bench.large --only quality:none,quality:dis_medium --no-peers     # ad hoc
    python -m bench.large --middlebury                    # the same variants on Middlebury (small motions)

Every method runs on the same grey frames (bench.common); per pair the methods run interleaved (one after
the other on that pair), so timing ratios are paired. A flow_node variant is ``PRESET:INITIALISATION``
(``none`` = the pyramid alone); its confidence output is scored by ROC AUC against the real error
(``flow_node.core.metrics.confidence_auc``). Library API: :func:`load_large`, :func:`variants`, :func:`run`.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from flow_node.core.api import FlowEstimator, to_grey
from flow_node.core.confidence import confidence
from flow_node.core.config import FlowConfig
from flow_node.core.flowio import read_flo, read_image
from flow_node.core.metrics import aee, confidence_auc

from .common import REPO, Pair, load_middlebury, machine, to_u8, write_json

DEFAULT_LARGE = REPO.parent / "shared" / "data" / "large"
DEFAULT_MIDDLEBURY = REPO.parent / "shared" / "data" / "middlebury"
RESULTS = REPO / "bench" / "results"
DEFAULT_VARIANTS = ("quality:none", "quality:dis_fine", "quality:dis_medium", "quality:dis_fast", "quality:sift",
                    "quality:orb",
                    "balanced:none", "balanced:dis_fast", "realtime:none", "realtime:dis_ultrafast",
                    "realtime:dis_fast", "fastest:none", "fastest:dis_ultrafast")

# (i0, i1) -> (flow (H, W, 2), confidence (H, W) or None)
Method = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray | None]]


def load_large(data: Path) -> list[Pair]:
    """frame0 -> frame1 with flow.flo for every pair folder under ``data`` (sorted by name)."""
    if not data.is_dir():
        raise SystemExit(f"large-displacement data not found at {data}; pass --data DIR")
    pairs = []
    for seq in sorted(p for p in data.iterdir() if (p / "flow.flo").is_file()):
        pairs.append(Pair(seq.name, to_grey(read_image(seq / "frame0.png"), "frame0"),
                          to_grey(read_image(seq / "frame1.png"), "frame1"), read_flo(seq / "flow.flo")))
    return pairs


def dis_method(preset: int) -> Method:
    import cv2

    algo = cv2.DISOpticalFlow_create(preset)
    return lambda i0, i1: (algo.calc(to_u8(i0), to_u8(i1), None).astype(np.float32), None)


def flow_node_variant(spec: str) -> tuple[FlowConfig, Method]:
    """``PRESET:INIT[:key=value,...]`` -> its config and method (JIT warm-up done here)."""
    parts = spec.split(":")
    cfg = FlowConfig.preset(parts[0]).replace(initialisation=parts[1] if len(parts) > 1 else "none")
    if len(parts) > 2:
        cfg = cfg.with_overrides(parts[2].split(","))
    est = FlowEstimator(cfg)
    est.warmup()

    def run(i0: np.ndarray, i1: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        flow = est.estimate(i0, i1).flow
        return flow, confidence(i0, i1, flow)

    return cfg, run


def variants(specs: tuple[str, ...], peers: bool) -> dict[str, Method]:
    """The methods of one run: DIS medium and ultrafast (if ``peers``), then each flow_node variant."""
    import cv2

    out: dict[str, Method] = {}
    if peers:
        out["opencv_dis_medium"] = dis_method(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
        out["opencv_dis_ultrafast"] = dis_method(cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST)
    for s in specs:
        out[f"flow_node:{s}"] = flow_node_variant(s)[1]
    return out


def run(methods: dict[str, Method], pairs: list[Pair], repeats: int = 1) -> dict[str, Any]:
    """Every method on every pair, interleaved per pair; seconds = the fastest of ``repeats`` runs.
    Returns {method: {per_pair: {name: {aee, seconds, auc}}, mean_aee, mean_seconds, mean_auc}}."""
    per: dict[str, dict[str, dict[str, Any]]] = {m: {} for m in methods}
    for p in pairs:
        for name, method in methods.items():
            best = float("inf")
            for _ in range(repeats):
                start = time.perf_counter()
                flow, conf = method(p.i0, p.i1)
                best = min(best, time.perf_counter() - start)
            rec: dict[str, Any] = {"aee": aee(flow, p.gt), "seconds": best}
            if conf is not None:
                rec["auc"] = confidence_auc(conf, flow, p.gt)
            per[name][p.name] = rec
        print(f"  {p.name}: " + ", ".join(f"{m.split(':', 1)[-1]} {r[p.name]['aee']:.2f}"
                                          for m, r in per.items()), flush=True)
    return {m: {"per_pair": r, **_means(r)} for m, r in per.items()}


def _means(per: dict[str, dict[str, Any]]) -> dict[str, float | None]:
    out: dict[str, float | None] = {}
    for key in ("aee", "seconds", "auc"):
        vals = [v[key] for v in per.values() if v.get(key) is not None]
        out[f"mean_{key}"] = float(np.mean(vals)) if vals else None
    return out


def table(results: dict[str, Any], pairs: list[Pair]) -> str:
    """A markdown table: mean AEE per pair, the mean, seconds relative to DIS medium, confidence AUC."""
    ref = results.get("opencv_dis_medium", {}).get("mean_seconds")
    head = "| method | " + " | ".join(p.name for p in pairs) + " | mean AEE | time / DIS medium | AUC |"
    lines = [head, "|" + "---|" * (len(pairs) + 4)]
    for name, r in results.items():
        cells = [f"{r['per_pair'][p.name]['aee']:.2f}" for p in pairs]
        rel = f"{r['mean_seconds'] / ref:.2f}" if ref else "-"
        auc = f"{r['mean_auc']:.3f}" if r.get("mean_auc") is not None else "-"
        lines.append(f"| {name} | " + " | ".join(cells) + f" | {r['mean_aee']:.3f} | {rel} | {auc} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=None, help="pairs folder (default ../shared/data/large)")
    ap.add_argument("--middlebury", action="store_true", help="run on the Middlebury training pairs instead")
    ap.add_argument("--only", default=",".join(DEFAULT_VARIANTS), help="comma-separated PRESET:INIT variants")
    ap.add_argument("--no-peers", action="store_true")
    ap.add_argument("--repeats", type=int, default=1, help="timing: fastest of N runs per pair and method")
    ap.add_argument("--output", type=Path, default=None, help="results JSON (default bench/results/large*.json)")
    args = ap.parse_args(argv)
    argv = sys.argv[1:] if argv is None else argv
    if args.middlebury:
        pairs = load_middlebury(args.data or DEFAULT_MIDDLEBURY)
    else:
        pairs = load_large(args.data or DEFAULT_LARGE)
    specs = tuple(s for s in args.only.split(",") if s)
    results = run(variants(specs, not args.no_peers), pairs, args.repeats)
    print(table(results, pairs))
    out = args.output or RESULTS / ("large_middlebury.json" if args.middlebury else "large.json")
    write_json(out, {"command": "python -m bench.large " + " ".join(argv), "machine": machine(),
                     "results": results})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
