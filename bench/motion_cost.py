"""What each ~/motion/* topic of the node costs per frame, as a ratio to the realtime preset's solve time.

    python -m bench.motion_cost                        # 320x240 and 640x480 -> bench/results/motion/motion_cost.json

The node computes a derived output only while its topic is subscribed (flow_node/ros/motion_outputs.py), so a
topic's cost is what the node's worker does for it when it is the only one subscribed: a fresh
MotionAnalysis of the pair, what the topic needs of it (the homography, the mask and the flag need the
dominant motion; the flag the mask) and the rclpy message (flow_node.pipeline.motion_msgs with the node's
RclpyKit), publishing excluded (it depends on the subscribers and the middleware: the mask and the
divergence are images like ~/magnitude). "all" is every topic at once (the dominant motion shared). The
confidence they take (all but the divergence) is reported on its own; each topic is timed twice: with the
confidence map given (~/confidence subscribed anyway: the node computes it once per pair for every consumer) and
without it ("+conf", what a topic costs when ~/confidence is not subscribed: as the node's MotionAnalysis.of, the
fits take the confidence at their samples alone, FlowEstimator.confidence_at, and the mask where it reads it alone,
FlowEstimator.confidence with ``where``; both with the estimator's backend, one confidence.Shared dict per pair as
FlowOutput keeps it: frame 1's planes computed once). "mask, whole map" is the mask +conf as it was before that
(the whole map first, the dominant motion reading it), timed in the same loop for the comparison, and so is the
mask +conf with its deviating pixels found by the numpy reference instead of the backend's kernel ("mask, numpy
deviating": as before numba_fits.deviating_numba). Pairs from
flow_node.bag.motion_scenes, exactly rendered, 8 bit: pans with an object covering 20 % and approaches.
The process keeps freed memory as the node does (flow_node.process.keep_freed_memory). Every time is the
best of ``--repeat`` runs, the engine's and the outputs' interleaved, in reverse order every other run (the
other load of the shared machine only adds time, and weighs on all of them alike; whichever runs first
after the engine pays for its cold caches). The fits run as the node runs them, with the engine's
backend's (derived.fits_for: numba kernels); the dominant motion, the homography and the TTC are also timed
with the numpy reference fits ("@numpy", confidence given), in the same loop.
"""

from __future__ import annotations

import argparse
import math
import sys
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
from flow_node.pipeline.motion import MotionDetector, deviating_pixels
from flow_node.pipeline.motion_msgs import motion_messages
from flow_node.process import keep_freed_memory
from flow_node.ros.motion_outputs import RclpyKit

from .common import REPO, machine, write_json
from .motion_regime import quantise8

CASES = (("pan", 0.2), ("approach", 0.0))  # (scene kind, object share)
NEEDS_CONFIDENCE = (*(t for t in MOTION_TOPICS if t != "motion/divergence"), "all")
WHOLE_MAP = "motion/moving_mask+map"  # the mask +conf with the whole map first (before confidence_in)
NUMPY_FIT_TOPICS = ("motion/dominant", "motion/homography", "motion/ttc")  # also with the numpy fits ("@numpy")
NUMPY_MASK = "motion/moving_mask+conf+npmask"  # the mask +conf, its deviating pixels by the numpy reference


def topic_time(flow: np.ndarray, conf: np.ndarray | Callable[[], np.ndarray], names: tuple[str, ...],
               confidence_at: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
               confidence_in: Callable[[np.ndarray], np.ndarray] | None = None, fits: Fits = NUMPY_FITS) -> float:
    """Seconds the node's worker spends on ``names`` for one pair, the confidence given or computed as
    needed (``conf`` a function, ``confidence_at`` its values at points, ``confidence_in`` where a mask is
    True; module docstring), the fits run by ``fits``."""
    header = Header(frame_id="camera")
    start = time.perf_counter()
    a = MotionAnalysis(flow, conf, 0.1, confidence_at=confidence_at, confidence_in=confidence_in, fits=fits)
    detected = MotionDetector().update(a.moving_fraction) if "motion/detected" in names else None
    for _ in motion_messages(RclpyKit(), header, a, detected, names):
        pass
    return time.perf_counter() - start


def _time(name: str, f0: np.ndarray, f1: np.ndarray, est: FlowEstimator, res: FlowResult, conf: np.ndarray) -> float:
    """Seconds of one run of ``name``: the engine on the pair, the confidence, a topic or "all" (with the
    confidence given, or with "+conf" computed as needed)."""
    start = time.perf_counter()
    if name == "engine":
        est.estimate(f0, f1)
        return time.perf_counter() - start
    if name == "confidence":
        est.confidence(*res.frames, res.flow)
        return time.perf_counter() - start
    if name.endswith("@numpy"):  # the numpy reference fits, the confidence given
        return topic_time(res.flow, conf, (name.removesuffix("@numpy"),), fits=NUMPY_FITS)
    fits = fits_for(est.backend)  # as the node's MotionAnalysis.of: the engine's backend's fits
    if name == NUMPY_MASK:
        fits, name = fits._replace(deviating=deviating_pixels), name.removesuffix("+npmask")
    topic = name.removesuffix("+conf").removesuffix("+map")
    names = tuple(MOTION_TOPICS) if topic == "all" else (topic,)
    if topic == name:
        return topic_time(res.flow, conf, names, fits=fits)
    shared: dict[str, np.ndarray] = {}  # what the pair's confidence calls share, as FlowOutput keeps it
    return topic_time(res.flow, lambda: est.confidence(*res.frames, res.flow, shared=shared or None), names,
                      lambda ys, xs: est.confidence_at(*res.frames, res.flow, ys, xs, shared=shared),
                      None if name == WHOLE_MAP else lambda where: est.confidence(*res.frames, res.flow, where,
                                                                                 shared=shared), fits)


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
            names = ("engine", "confidence", *MOTION_TOPICS, "all", *(f"{t}+conf" for t in NEEDS_CONFIDENCE),
                     WHOLE_MAP, NUMPY_MASK, *(f"{t}@numpy" for t in NUMPY_FIT_TOPICS))
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
    for name in NUMPY_FIT_TOPICS:  # the same topic with the numpy reference fits (same run, interleaved)
        t = np.array([r[f"{name}@numpy_s"] for r in rows])
        out[name] |= {"numpy_fits_ratio_median": float(np.median(t / engine)),
                      "numpy_fits_ms_median": 1e3 * float(np.median(t))}
    tm = np.array([r[f"{WHOLE_MAP}_s"] for r in rows])
    tn = np.array([r[f"{NUMPY_MASK}_s"] for r in rows])
    out["motion/moving_mask"] |= {"whole_map_ratio_median": float(np.median(tm / engine)),
                                  "whole_map_ms_median": 1e3 * float(np.median(tm)),
                                  "numpy_deviating_ratio_median": float(np.median(tn / engine)),
                                  "numpy_deviating_ms_median": 1e3 * float(np.median(tn))}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="320x240,640x480", help="comma-separated WxH")
    ap.add_argument("--pairs", type=int, default=3, help="pairs per scene kind and size")
    ap.add_argument("--repeat", type=int, default=5, help="time each this often, keep the best")
    ap.add_argument("--seed", type=int, default=4100)
    ap.add_argument("--output", type=Path, default=REPO / "bench" / "results" / "motion" / "motion_cost.json")
    args = ap.parse_args(argv)
    argv = sys.argv[1:] if argv is None else argv
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
    print(f"{'mask, whole map':22s}" + "".join(
        f"{100 * r['summary']['motion/moving_mask']['whole_map_ratio_median']:48.2f} %" for r in results.values()))
    print(f"{'mask, numpy deviating':22s}" + "".join(
        f"{100 * r['summary']['motion/moving_mask']['numpy_deviating_ratio_median']:48.2f} %"
        for r in results.values()))
    for name in NUMPY_FIT_TOPICS:
        print(f"{name + ' numpy fits':22s}" + "".join(
            f"{100 * r['summary'][name]['numpy_fits_ratio_median']:6.2f} % "
            f"{r['summary'][name]['numpy_fits_ms_median']:6.2f} ms" + " " * 14 for r in results.values()))
    print(f"{'realtime (ms)':22s}" + "".join(f"{r['summary']['engine_ms_median']:19.1f} ms" for r in results.values()))
    write_json(args.output, {"command": "python -m bench.motion_cost " + " ".join(argv), "machine": machine(),
                             "results": results})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
