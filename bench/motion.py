"""The derived motion outputs (issue 28) on exactly rendered scenes (flow_node.bag.motion_scenes) through the
``realtime`` preset, as ratios to the engine's time on the same pair; what ``score`` and ``cost`` measure:
docs/node.md, "Derived outputs" (accuracy and cost, "Cost per frame").

    python -m bench.motion score [--pairs 6] [--size 320x240] [--noise 0]   # -> bench/results/motion/motion_regime.json
    python -m bench.motion cost [--sizes 320x240,640x480] [--repeat 5]      # -> bench/results/motion/motion_cost.json
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from flow_node.bag.motion_scenes import TTC_FRAMES, MotionTruth, motion_scene
from flow_node.bag.scenes import Scene, render_grey_pair
from flow_node.core import FlowEstimator
from flow_node.core.confidence import confidence
from flow_node.core.config import FlowConfig
from flow_node.pipeline.derived import MOTION_TOPICS, Fits, MotionAnalysis, fits_for

from .common import REPO, run_record, write_json, wxh
from .suite.synthetic import quantise

OUT = REPO / "bench" / "results" / "motion"
OUTPUTS = ("dominant", "divergence", "ttc", "foe", "moving_mask")
SHARES = (0.0, 0.1, 0.2, 0.3)  # objects' share of the frame, cycled over the pairs of a camera motion
NEEDS_CONFIDENCE = (*(t for t in MOTION_TOPICS if t != "motion/divergence"), "all")


def rendered(kind: str, size: tuple[int, int], seed: int, share: float, noise: float = 0.0, **kw: Any
             ) -> tuple[Scene, MotionTruth, np.ndarray, np.ndarray]:
    """One scene of ``kind`` (motion_scene's keywords ``kw``), its truth and its two uint8 frames (a camera's
    8 bit, after Gaussian noise of ``noise`` grey levels)."""
    scene, truth = motion_scene(kind, size, np.random.default_rng(seed), share, **kw)
    frames = render_grey_pair(scene)[:2]
    if noise > 0.0:
        frames = tuple(f + np.random.default_rng([seed + k, 7]).normal(0.0, noise / 255.0, f.shape)
                       for k, f in enumerate(frames))
    return scene, truth, quantise(frames[0], 8), quantise(frames[1], 8)


def estimator(size: tuple[int, int]) -> FlowEstimator:
    """The ``realtime`` estimator, warm for ``size`` (W, H)."""
    est = FlowEstimator(FlowConfig.preset("realtime"))
    est.warmup(size[::-1])
    return est


def best_time(fn: Callable[[], Any], repeat: int) -> tuple[Any, float]:
    """``fn()``'s value and its shortest time over ``repeat`` runs (s): other load only ever adds time."""
    best, value = math.inf, None
    for _ in range(repeat):
        start = time.perf_counter()
        value = fn()
        best = min(best, time.perf_counter() - start)
    return value, best


def median(values: list[float | None]) -> float | None:
    vals = [v for v in values if v is not None]
    return float(np.median(vals)) if vals else None


def cases(pairs: int, seed: int) -> list[tuple[str, float, int, float | None]]:
    """score's (kind, object share, seed, TTC frames) of every pair: camera motions with 10-30 % objects and
    alone, still scenes, approaches at TTCs spread log-evenly over 10-200 frames."""
    out: list[tuple[str, float, int, float | None]] = []
    for k, tau in enumerate(np.geomspace(*TTC_FRAMES, pairs) if pairs > 1 else [math.sqrt(np.prod(TTC_FRAMES))]):
        for j, kind in enumerate(("pan", "rotation", "zoom")):
            out += [(kind, SHARES[1 + (k + j) % 3], seed + 100 * j + k, None),  # 10-30 % objects
                    (kind, 0.0, seed + 1000 + 100 * j + k, None)]  # static scene: only the camera moves
        out += [("approach", 0.0, seed + 500 + k, float(tau)), ("still", 0.0, seed + 600 + k, None)]
    return out


def score(case: tuple[str, float, int, float | None], size: tuple[int, int], est: FlowEstimator, repeat: int,
          noise: float) -> dict[str, Any]:
    """One pair: render, solve, every output timed alone (the mask after its dominant motion), errors."""
    kind, share, seed, tau = case
    scene, truth, f0, f1 = rendered(kind, size, seed, share, noise, ttc_frames=tau)
    res, t_engine = best_time(lambda: est.estimate(f0, f1), repeat)
    conf, t_conf = best_time(lambda: confidence(*res.frames, res.flow), repeat)
    fits = fits_for(est.backend)
    row: dict[str, Any] = {"kind": kind, "seed": seed, "object_share": truth.object_share, "engine_s": t_engine,
                           "confidence_s": t_conf}
    for name in OUTPUTS:
        def output(name: str = name) -> float:
            a = MotionAnalysis(res.flow, conf, 0.1, fits=fits)
            if name == "moving_mask":
                a.dominant  # noqa: B018
            start = time.perf_counter()
            getattr(a, name)
            return time.perf_counter() - start
        row[f"{name}_s"] = min(output() for _ in range(repeat))
    a, objects = MotionAnalysis(res.flow, conf, 0.1, fits=fits), scene.layer_map(0) > 0
    d, mask = a.dominant, a.moving_mask > 0
    row["moving_fraction"] = a.moving_fraction
    if d is not None:
        row |= {"translation_err_px": math.hypot(d.tx - truth.tx, d.ty - truth.ty),
                "rotation_err_deg": abs(d.rotation_deg - truth.rotation_deg), "scale_err": abs(d.scale - truth.scale),
                "inlier_share": d.inlier_share}
    if objects.any():
        row["mask_iou"] = float(np.sum(mask & objects) / max(1, np.sum(mask | objects)))
    if truth.ttc_frames is not None:
        ttc = [t if math.isfinite(t) else None for t in a.ttc.grid("ttc_frames").ravel()]
        row |= {"ttc_true": truth.ttc_frames, "ttc_regions": ttc,
                "ttc_rel_err": [None if t is None else abs(t - truth.ttc_frames) / truth.ttc_frames for t in ttc]}
        foe = a.foe
        row["foe_err_px"] = None if foe is None else math.hypot(foe.x - truth.foe[0], foe.y - truth.foe[1])
    return row


def summarise_score(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The figures the issue targets, with the targets."""
    moving = [r for r in rows if r["object_share"] > 0]
    static = [r for r in rows if r["object_share"] == 0 and r["kind"] != "approach"]
    camera = [r for r in rows if r["kind"] in ("pan", "rotation")]
    approach = [r for r in rows if r["kind"] == "approach"]
    engine = np.array([r["engine_s"] for r in rows])

    def spread(sel: list[dict[str, Any]], key: str, worst: Callable = max, **target: float) -> dict[str, Any]:
        return {("min" if worst is min else "max"): worst(r[key] for r in sel),
                "median": median([r[key] for r in sel]), **target}
    rel = [e for r in approach for e in r["ttc_rel_err"]]
    return {
        "translation_err_px": spread(camera, "translation_err_px", target_max=0.05),
        "rotation_err_deg": spread(camera, "rotation_err_deg", target_max=0.05),
        "ttc_rel_err": {"median": median(rel), "centre_median": median([r["ttc_rel_err"][4] for r in approach]),
                        "missing": sum(e is None for e in rel), "target_median": 0.15},
        "foe_err_px_median": median([r["foe_err_px"] for r in approach]),
        "mask_iou": spread(moving, "mask_iou", min, target=0.8),
        "static_false_positive": spread(static, "moving_fraction", target_max=0.01),
        "time_ratio_median": {name: float(np.median(np.array([r[f"{name}_s"] for r in rows]) / engine))
                              for name in (*OUTPUTS, "confidence")} | {"target_max": 0.10},
        "engine_ms_median": 1e3 * float(np.median(engine)),
    }


def topic_time(name: str, est: FlowEstimator, f0: np.ndarray, f1: np.ndarray, res: Any, conf: np.ndarray) -> float:
    """cost: seconds of one run of ``name``: the engine on the pair, the confidence, a topic or "all" (the
    confidence given, or with "+conf" computed as needed, as the node's MotionAnalysis.of), the messages built."""
    from std_msgs.msg import Header

    from flow_node.pipeline.motion import MotionDetector
    from flow_node.pipeline.motion_msgs import motion_messages
    from flow_node.ros.motion_outputs import RclpyKit

    start = time.perf_counter()
    if name in ("engine", "confidence"):
        est.estimate(f0, f1) if name == "engine" else est.confidence(*res.frames, res.flow)
        return time.perf_counter() - start
    topic = name.removesuffix("+conf")
    names = tuple(MOTION_TOPICS) if topic == "all" else (topic,)
    fits: Fits = fits_for(est.backend)  # the engine's backend's fits, as in the node
    if topic == name:
        a = MotionAnalysis(res.flow, conf, 0.1, fits=fits)
    else:
        shared: dict[str, np.ndarray] = {}  # what the pair's confidence calls share, as FlowOutput keeps it
        a = MotionAnalysis(res.flow, lambda: est.confidence(*res.frames, res.flow, shared=shared or None), 0.1,
                           confidence_at=lambda ys, xs: est.confidence_at(*res.frames, res.flow, ys, xs, shared=shared),
                           confidence_in=lambda where: est.confidence(*res.frames, res.flow, where, shared=shared),
                           fits=fits)
    detected = MotionDetector().update(a.moving_fraction) if "motion/detected" in names else None
    for _ in motion_messages(RclpyKit(), Header(frame_id="camera"), a, detected, names):
        pass
    return time.perf_counter() - start


def cost(size: tuple[int, int], pairs: int, repeat: int, seed: int) -> dict[str, Any]:
    """cost on ``pairs`` pans (20 % objects) and approaches of ``size``: per pair the best time of each name,
    interleaved (the order reversed every other time); the medians of time / the engine's."""
    est, rows = estimator(size), []
    names = ("engine", "confidence", *MOTION_TOPICS, "all", *(f"{t}+conf" for t in NEEDS_CONFIDENCE))
    for k in range(pairs):
        for j, (kind, share) in enumerate((("pan", 0.2), ("approach", 0.0))):
            _, _, f0, f1 = rendered(kind, size, seed + 10 * k + j, share, objects=1)
            res = est.estimate(f0, f1)
            conf = est.confidence(*res.frames, res.flow)
            times: dict[str, float] = {}
            for r in range(repeat):
                for name in names[:: 1 if r % 2 == 0 else -1]:
                    times[name] = min(times.get(name, math.inf), topic_time(name, est, f0, f1, res, conf))
            rows.append({"kind": kind} | {f"{name}_s": t for name, t in times.items()})
            print(f"{size[0]}x{size[1]} {kind}: engine {1e3 * times['engine']:.1f} ms, all {1e3 * times['all']:.2f} "
                  f"ms, confidence {1e3 * times['confidence']:.2f} ms", flush=True)
    engine = np.array([r["engine_s"] for r in rows])
    out: dict[str, Any] = {"engine_ms_median": 1e3 * float(np.median(engine))}
    for name in (*MOTION_TOPICS, "all", "confidence"):
        for suffix, key in (("", ""), ("+conf", "with_confidence_")) if name in NEEDS_CONFIDENCE else (("", ""),):
            t = np.array([r[f"{name}{suffix}_s"] for r in rows])
            out.setdefault(name, {}).update({f"{key}ratio_median": float(np.median(t / engine)),
                                             f"{key}ms_median": 1e3 * float(np.median(t))})
    return {"summary": out, "pairs": rows}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.motion", description=__doc__.splitlines()[0])
    modes = ap.add_subparsers(dest="mode", required=True)
    sc = modes.add_parser("score")
    sc.add_argument("--pairs", type=int, default=6, help="pairs per scene kind")
    sc.add_argument("--size", default="320x240", help="WxH")
    sc.add_argument("--seed", type=int, default=2800, help="first seed (tests use others)")
    sc.add_argument("--repeat", type=int, default=3, help="time the engine and each output this often, keep the best")
    sc.add_argument("--noise", type=float, default=0.0, help="Gaussian sensor noise, grey levels of 255")
    co = modes.add_parser("cost")
    co.add_argument("--sizes", default="320x240,640x480", help="comma-separated WxH")
    co.add_argument("--pairs", type=int, default=3, help="pairs per scene kind and size")
    co.add_argument("--repeat", type=int, default=5, help="time each this often, keep the best")
    co.add_argument("--seed", type=int, default=4100)
    for p, name in ((sc, "motion_regime"), (co, "motion_cost")):
        p.add_argument("--output", type=Path, default=OUT / f"{name}.json")
    args = ap.parse_args(argv)
    head = run_record("bench.motion", argv)  # the command, and the load as it starts
    if args.mode == "cost":
        from flow_node.process import keep_freed_memory

        keep_freed_memory()  # as the node's main() does: arrays freed by one frame serve the next
        results = {s: cost(wxh(s), args.pairs, args.repeat, args.seed)
                   for s in args.sizes.split(",")}
        print(f"{'topic':22s}" + "".join(f"{s:>22s}{s + ' +conf':>14s}" for s in results))
        for name in (*MOTION_TOPICS, "all", "confidence"):
            cells = [f"{100 * s[name]['ratio_median']:6.2f} % {s[name]['ms_median']:6.2f} ms"
                     + (f"{100 * s[name]['with_confidence_ratio_median']:12.2f} %" if name in NEEDS_CONFIDENCE
                        else " " * 14) for s in (r["summary"] for r in results.values())]
            print(f"{name:22s}" + "".join(f"{c:>36s}" for c in cells))
        print(f"{'realtime (ms)':22s}" + "".join(f"{r['summary']['engine_ms_median']:19.1f} ms"
                                              for r in results.values()))
        write_json(args.output, {**head, "results": results})
        return 0
    size = wxh(args.size)
    est, rows = estimator(size), []
    for case in cases(args.pairs, args.seed):
        rows.append(r := score(case, size, est, args.repeat, args.noise))
        print(f"{case[0]:9s} share {r['object_share']:.2f} seed {case[2]}: "
              f"t {r.get('translation_err_px', math.nan):.4f}"
              f" rot {r.get('rotation_err_deg', math.nan):.4f} iou {r.get('mask_iou', math.nan):.3f} moving "
              f"{r['moving_fraction']:.4f} ttc {median(r.get('ttc_rel_err', [None]))}", flush=True)
    summary = summarise_score(rows)
    print(summary)
    write_json(args.output, {**head, "size": list(size), "noise": args.noise, "summary": summary, "pairs": rows})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
