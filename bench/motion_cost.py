"""What each ~/motion/* topic of the node costs per frame, as a ratio to the realtime preset's solve time.

    python -m bench.motion_cost                        # 320x240 and 640x480 -> bench/results/motion/motion_cost.json

What is timed and how (each topic alone, with the confidence given and "+conf" computed as the node does,
interleaved with the engine, best of ``--repeat``): docs/node.md, "Cost per frame". The same topics with the
numpy reference fits, the mask with the whole confidence map first and with the numpy deviating pixels were
one-off comparisons, retired: ``git show 2cc837f:bench/motion_cost.py``.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from std_msgs.msg import Header

from flow_node.bag.motion_scenes import motion_scene
from flow_node.bag.scenes import render_grey_pair
from flow_node.core import FlowEstimator, FlowResult
from flow_node.core.config import FlowConfig
from flow_node.pipeline.derived import MOTION_TOPICS, NUMPY_FITS, Fits, MotionAnalysis, fits_for
from flow_node.pipeline.motion import MotionDetector
from flow_node.pipeline.motion_msgs import motion_messages
from flow_node.process import keep_freed_memory
from flow_node.ros.motion_outputs import RclpyKit

from .common import REPO, run_record, write_json
from .motion_regime import quantise8

CASES = (("pan", 0.2), ("approach", 0.0))  # (scene kind, object share)
NEEDS_CONFIDENCE = (*(t for t in MOTION_TOPICS if t != "motion/divergence"), "all")


def topic_time(flow: np.ndarray, conf: np.ndarray | Callable[[], np.ndarray], names: tuple[str, ...],
               confidence_at: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
               confidence_in: Callable[[np.ndarray], np.ndarray] | None = None, fits: Fits = NUMPY_FITS) -> float:
    """Seconds the node's worker spends on ``names`` for one pair, the confidence given or computed as
    needed (``conf`` a function, ``confidence_at`` its values at points, ``confidence_in`` where a mask is
    True), the fits run by ``fits``."""
    header = Header(frame_id="camera")
    start = time.perf_counter()
    a = MotionAnalysis(flow, conf, 0.1, confidence_at=confidence_at, confidence_in=confidence_in, fits=fits)
    detected = MotionDetector().update(a.moving_fraction) if "motion/detected" in names else None
    for _ in motion_messages(RclpyKit(), header, a, detected, names):
        pass
    return time.perf_counter() - start


def _time(name: str, f0: np.ndarray, f1: np.ndarray, est: FlowEstimator, res: FlowResult, conf: np.ndarray) -> float:
    """Seconds of one run of ``name``: the engine on the pair, the confidence, a topic or "all" (with the
    confidence given, or with "+conf" computed as needed, as the node's MotionAnalysis.of)."""
    start = time.perf_counter()
    if name == "engine":
        est.estimate(f0, f1)
        return time.perf_counter() - start
    if name == "confidence":
        est.confidence(*res.frames, res.flow)
        return time.perf_counter() - start
    fits = fits_for(est.backend)  # the engine's backend's fits, as in the node
    topic = name.removesuffix("+conf")
    names = tuple(MOTION_TOPICS) if topic == "all" else (topic,)
    if topic == name:
        return topic_time(res.flow, conf, names, fits=fits)
    shared: dict[str, np.ndarray] = {}  # what the pair's confidence calls share, as FlowOutput keeps it
    return topic_time(res.flow, lambda: est.confidence(*res.frames, res.flow, shared=shared or None), names,
                      lambda ys, xs: est.confidence_at(*res.frames, res.flow, ys, xs, shared=shared),
                      lambda where: est.confidence(*res.frames, res.flow, where, shared=shared), fits)


def measure(size: tuple[int, int], pairs: int, repeat: int, seed: int) -> list[dict[str, Any]]:
    est = FlowEstimator(FlowConfig.preset("realtime"))
    est.warmup(size[::-1])
    rows = []
    for k in range(pairs):
        for j, (kind, share) in enumerate(CASES):
            scene, _ = motion_scene(kind, size, np.random.default_rng(seed + 10 * k + j), share, objects=1)
            i0, i1, _ = render_grey_pair(scene)
            f0, f1 = quantise8(i0, 0.0, seed), quantise8(i1, 0.0, seed + 1)
            res = est.estimate(f0, f1)
            conf = est.confidence(*res.frames, res.flow)
            times: dict[str, float] = {}
            names = ("engine", "confidence", *MOTION_TOPICS, "all", *(f"{t}+conf" for t in NEEDS_CONFIDENCE))
            for r in range(repeat):  # interleaved, so that the machine's load weighs on all of them alike, the
                for name in names if r % 2 == 0 else names[::-1]:  # order reversed every other time (first: dearer)
                    times[name] = min(times.get(name, math.inf), _time(name, f0, f1, est, res, conf))
            row: dict[str, Any] = {"kind": kind} | {f"{name}_s": t for name, t in times.items()}
            rows.append(row)
            print(f"{size[0]}x{size[1]} {kind}: engine {1e3 * row['engine_s']:.1f} ms, all {1e3 * row['all_s']:.2f} "
                  f"ms, confidence {1e3 * row['confidence_s']:.2f} ms", flush=True)
    return rows


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Median over the pairs of each topic's time / the engine's, and of the times themselves (ms)."""
    engine = np.array([r["engine_s"] for r in rows])
    out: dict[str, Any] = {"engine_ms_median": 1e3 * float(np.median(engine))}
    for name in (*MOTION_TOPICS, "all", "confidence"):
        t = np.array([r[f"{name}_s"] for r in rows])
        out[name] = {"ratio_median": float(np.median(t / engine)), "ms_median": 1e3 * float(np.median(t))}
        if name in NEEDS_CONFIDENCE:  # what the topic costs when ~/confidence is not subscribed anyway
            tc = np.array([r[f"{name}+conf_s"] for r in rows])
            out[name] |= {"with_confidence_ratio_median": float(np.median(tc / engine)),
                          "with_confidence_ms_median": 1e3 * float(np.median(tc))}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="320x240,640x480", help="comma-separated WxH")
    ap.add_argument("--pairs", type=int, default=3, help="pairs per scene kind and size")
    ap.add_argument("--repeat", type=int, default=5, help="time each this often, keep the best")
    ap.add_argument("--seed", type=int, default=4100)
    ap.add_argument("--output", type=Path, default=REPO / "bench" / "results" / "motion" / "motion_cost.json")
    args = ap.parse_args(argv)
    head = run_record("bench.motion_cost", argv)  # the command, and the load as it starts
    keep_freed_memory()  # as the node's main() does: arrays freed by one frame serve the next
    results = {}
    for text in args.sizes.split(","):
        size = tuple(int(v) for v in text.lower().split("x"))
        rows = measure(size, args.pairs, args.repeat, args.seed)
        results[text] = {"summary": summarise(rows), "pairs": rows}
    print(f"{'topic':22s}" + "".join(f"{s:>22s}{s + ' +conf':>14s}" for s in results))
    for name in (*MOTION_TOPICS, "all", "confidence"):
        cells = [f"{100 * r['summary'][name]['ratio_median']:6.2f} % {r['summary'][name]['ms_median']:6.2f} ms"
                 + (f"{100 * r['summary'][name]['with_confidence_ratio_median']:12.2f} %"
                    if name in NEEDS_CONFIDENCE else " " * 14) for r in results.values()]
        print(f"{name:22s}" + "".join(f"{c:>36s}" for c in cells))
    print(f"{'realtime (ms)':22s}" + "".join(f"{r['summary']['engine_ms_median']:19.1f} ms" for r in results.values()))
    write_json(args.output, {**head, "results": results})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
