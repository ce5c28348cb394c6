"""Speed (issue 3): the presets against the peers in one run, kernel time vs memory floor, JIT cost, scaling.

    .venv-bench/bin/python -m bench.speed     # -> bench/results/speed.json, bench/speed_frontier.png,
                                              #    the tables printed as Markdown (about 15 min)

Everything timed here runs in this one process, one method after the other on the same frames, so the
ratios (against OpenCV DualTVL1 and DIS) compare like with like even on a shared, noisy machine.

- Middlebury training pairs (8) and RubberWhale upscaled to 1280x720: per pair the median of --repeats
  runs after one warm-up run, the methods' runs interleaved (round-robin), AEE of the last run; peers
  OpenCV DualTVL1 (defaults), scikit-image TV-L1 (defaults), OpenCV DIS medium and ultrafast, Farneback
  (OpenCV's documented example parameters).
- cold start: a fresh interpreter with an empty NUMBA_CACHE_DIR imports the engine and calls warmup()
  (JIT compile), then estimates the first real frame; again with the now-filled cache.
- kernel: one L1-TV primal-dual iteration at 640x480 (serial and parallel kernels) against the memory
  floor: the bytes the two passes must move divided by the bandwidth of a streaming kernel over an
  equally large working set, measured in the same run.
- scaling: preset time at 320x240, 640x480, 1280x720, 1920x1080.
- frontier: time vs AEE for a range of settings around the fast presets (PNG plot).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig
from flow_node.core.metrics import aee

from .common import (
    DEFAULT_DATA,
    PEERS,
    REPO,
    SEQUENCES,
    Method,
    Pair,
    load_middlebury,
    machine,
    to_u8,
    write_json,
)

RESULTS = REPO / "bench" / "results"
PRESETS_TIMED = ("quality", "realtime", "fastest")
SIZES = ((320, 240), (640, 480), (1280, 720), (1920, 1080))

# Settings around the fast presets (over the realtime preset) for the time-vs-AEE frontier: the finest
# solved level (0 = full resolution, 1 = half, 2 = quarter) and the work per level.
FRONTIER: list[dict[str, Any]] = [
    dict(finest_level=2, iterations=8, median_filter=3),  # = fastest
    dict(finest_level=2),
    dict(finest_level=1, iterations=8),
    dict(finest_level=1),  # = realtime
    dict(finest_level=1, warps=3),
    dict(finest_level=1, warps=3, iterations=15),
    dict(finest_level=0, warps=1),
    dict(finest_level=0),
    dict(finest_level=0, iterations=20),
    dict(finest_level=0, warps=3, iterations=30),
]


# ------------------------------------------------------------------------------------------- methods
def dis(preset: str) -> Method:
    """OpenCV DIS with the named preset (MEDIUM, ULTRAFAST, FAST)."""
    algo = cv2.DISOpticalFlow_create(getattr(cv2, f"DISOPTICAL_FLOW_PRESET_{preset}"))
    return lambda i0, i1: algo.calc(to_u8(i0), to_u8(i1), None).astype(np.float32)


def farneback() -> Method:
    """OpenCV Farneback with the parameters of OpenCV's own optical-flow example."""
    return lambda i0, i1: cv2.calcOpticalFlowFarneback(to_u8(i0), to_u8(i1), None, 0.5, 3, 15, 3, 5, 1.2,
                                                       0).astype(np.float32)


def engine(cfg: FlowConfig) -> Method:
    est = FlowEstimator(cfg)
    est.warmup()
    return lambda i0, i1: est.estimate(i0, i1).flow


def methods() -> dict[str, Callable[[], Method]]:
    out: dict[str, Callable[[], Method]] = {f"flow_node:{p}": (lambda p=p: engine(FlowConfig.preset(p)))
                                            for p in PRESETS_TIMED}
    out.update({
        "opencv_dualtvl1": PEERS["opencv_dualtvl1"],
        "skimage_tvl1": PEERS["skimage_tvl1"],
        "opencv_dis_medium": lambda: dis("MEDIUM"),
        "opencv_dis_ultrafast": lambda: dis("ULTRAFAST"),
        "opencv_farneback": farneback,
    })
    return out


# ---------------------------------------------------------------------------------------------- data
def resize_pair(p: Pair, size: tuple[int, int], name: str) -> Pair:
    """Pair resampled to size (w, h): frames bicubic, flow bilinear with vectors rescaled, unknowns kept."""
    w, h = size
    sx, sy = w / p.i0.shape[1], h / p.i0.shape[0]
    unknown = ~(np.abs(p.gt) < 1e9).all(axis=-1)
    gt = np.where(unknown[..., None], 0.0, p.gt).astype(np.float32)
    gt = cv2.resize(gt, (w, h), interpolation=cv2.INTER_LINEAR) * np.array([sx, sy], np.float32)
    bad = cv2.resize(unknown.astype(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST).astype(bool)
    gt[bad] = 1e10
    frames = [np.clip(cv2.resize(i, (w, h), interpolation=cv2.INTER_CUBIC), 0, 1) for i in (p.i0, p.i1)]
    return Pair(name, frames[0], frames[1], gt)


# ----------------------------------------------------------------------------------------- timing
def time_pairs(method: Method, pairs: list[Pair], repeats: int) -> dict[str, dict[str, float]]:
    """Per pair: median seconds of ``repeats`` runs (after one untimed run) and the AEE."""
    out = {}
    for p in pairs:
        flow = method(p.i0, p.i1)
        secs = []
        for _ in range(repeats):
            start = time.perf_counter()
            flow = method(p.i0, p.i1)
            secs.append(time.perf_counter() - start)
        out[p.name] = {"seconds": float(np.median(secs)), "aee": aee(flow, p.gt)}
    return out


def middlebury_table(pairs: list[Pair], repeats: int, slow_repeats: int) -> dict[str, Any]:
    """Every method on every pair, then ratios against DualTVL1 and DIS (same run).

    Round-robin: on each pair every method runs once untimed, then the timed runs alternate between the
    methods (slow peers stop after ``slow_repeats``), so load changes on a shared machine hit all methods
    alike instead of whichever happened to run at the time."""
    made = {name: make() for name, make in methods().items()}
    reps = {name: slow_repeats if name in ("opencv_dualtvl1", "skimage_tvl1") else repeats for name in made}
    res: dict[str, Any] = {name: {"per_pair": {}, "runs_per_pair": reps[name]} for name in made}
    for p in pairs:
        print(f"  {p.name}", flush=True)
        flows = {name: m(p.i0, p.i1) for name, m in made.items()}
        secs: dict[str, list[float]] = {name: [] for name in made}
        for r in range(max(reps.values())):
            for name, m in made.items():
                if r < reps[name]:
                    start = time.perf_counter()
                    flows[name] = m(p.i0, p.i1)
                    secs[name].append(time.perf_counter() - start)
        for name in made:
            res[name]["per_pair"][p.name] = {"seconds": float(np.median(secs[name])),
                                             "aee": aee(flows[name], p.gt)}
    mb = [p.name for p in pairs if p.name != "RubberWhale_1280x720"]
    for r in res.values():
        per = r["per_pair"]
        r["mean_seconds"] = float(np.mean([per[n]["seconds"] for n in mb]))
        r["mean_aee"] = float(np.mean([per[n]["aee"] for n in mb]))
        for peer in ("opencv_dualtvl1", "opencv_dis_medium", "opencv_dis_ultrafast"):
            ratios = [per[n]["seconds"] / res[peer]["per_pair"][n]["seconds"] for n in per]
            r[f"time_ratio_vs_{peer}"] = {n: float(x) for n, x in zip(per, ratios, strict=True)}
            r[f"mean_time_ratio_vs_{peer}"] = float(np.mean([r[f"time_ratio_vs_{peer}"][n] for n in mb]))
            r[f"pairs_faster_than_{peer}"] = int(sum(x < 1.0 for n, x in zip(per, ratios, strict=True) if n in mb))
    return res


# ---------------------------------------------------------------------------------------- cold start
COLD_CHILD = """
import json, sys, time
t0 = time.perf_counter()
import numpy as np
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig
t1 = time.perf_counter()
est = FlowEstimator(FlowConfig.preset(sys.argv[1]))
warm = est.warmup()
f = np.load(sys.argv[2])
t2 = time.perf_counter()
est.estimate(f[0], f[1])
t3 = time.perf_counter()
est.estimate(f[0], f[1])
t4 = time.perf_counter()
print(json.dumps({"import_s": t1 - t0, "warmup_s": warm, "first_frame_s": t3 - t2, "second_frame_s": t4 - t3,
                  "backend": est.backend}))
"""


def cold_start(pair: Pair, preset: str) -> dict[str, Any]:
    """JIT cost: fresh interpreters with an empty, then a filled numba cache directory."""
    out: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        frames = Path(tmp) / "pair.npy"
        np.save(frames, np.stack([pair.i0, pair.i1]))
        env = dict(os.environ, NUMBA_CACHE_DIR=str(Path(tmp) / "numba_cache"))
        for label in ("cold_cache", "warm_cache"):
            run = subprocess.run([sys.executable, "-c", COLD_CHILD, preset, str(frames)], env=env,
                                 capture_output=True, text=True, check=True)
            out[label] = json.loads(run.stdout.strip().splitlines()[-1])
    return out


# ------------------------------------------------------------------------------------------ kernel
def kernel_vs_floor(shape: tuple[int, int] = (480, 640), iters: int = 50) -> dict[str, Any]:
    """L1-TV iteration time (serial / parallel kernels) vs the memory-traffic floor, same run."""

    from flow_node.core import numba_backend as nb
    from flow_node.core.models import MODEL_SPECS
    from flow_node.core.solver import PDState, Problem, SolveParams

    h, w = shape
    rng = np.random.default_rng(0)
    a = (0.1 * rng.standard_normal((2, h, w))).astype(np.float32)
    c = (0.05 * rng.standard_normal((h, w))).astype(np.float32)
    spec = MODEL_SPECS["l1_tv"]
    params = SolveParams(spec, 0.025, 0.5, "isotropic", iters, 0.0)
    # floats moved per pixel: dual reads v_bar (2), y (4), writes y (4); primal reads y (4), v (2), a (2),
    # c (1), writes v (2), v_bar (2)
    bytes_per_iter = 23 * 4 * h * w
    out: dict[str, Any] = {"shape": [h, w], "bytes_per_iteration": bytes_per_iter}
    saved = nb.PARALLEL_MIN_PIXELS
    for label, threads, min_px in (("serial", 1, 10**12), ("parallel", 0, 0)):
        nb.PARALLEL_MIN_PIXELS = min_px
        st = PDState.zeros(spec, shape)
        with nb.thread_count(threads) as used:
            nb.solve_numba(Problem(a, c), st, params)
            secs = []
            for _ in range(7):
                start = time.perf_counter()
                nb.solve_numba(Problem(a, c), st, params)
                secs.append((time.perf_counter() - start) / iters)
        bw = _stream_bandwidth(h * w, used)
        per_iter = float(np.median(secs))
        floor = bytes_per_iter / bw
        out[label] = {"ms_per_iteration": per_iter * 1e3, "threads": used, "stream_GBps": bw / 1e9,
                      "floor_ms": floor * 1e3, "ratio_to_floor": per_iter / floor}
    nb.PARALLEL_MIN_PIXELS = saved
    return out


def _stream_bandwidth(pixels: int, threads: int) -> float:
    """Bytes/s of a streaming copy-scale kernel (dst = 1.0001 src over flat float32 arrays) that moves as
    many bytes as one iteration (23 planes: 11.5 read, 11.5 written), with the given threads."""
    import numba

    stream_par, stream_ser = _stream_kernels()
    n = 23 * pixels // 2
    src = np.ones(n, np.float32)
    dst = np.zeros(n, np.float32)
    fn = stream_par if threads > 1 else stream_ser
    numba.set_num_threads(max(threads, 1))
    fn(src, dst)
    secs = []
    for _ in range(20):
        start = time.perf_counter()
        fn(src, dst)
        secs.append(time.perf_counter() - start)
    return (src.nbytes + dst.nbytes) / float(np.median(secs))


def _stream_kernels() -> tuple[Callable, Callable]:
    from numba import njit, prange

    def body(src, dst):  # noqa: ANN001, ANN202
        for j in prange(src.shape[0]):
            dst[j] = src[j] * np.float32(1.0001)

    return njit(parallel=True, fastmath=True)(body), njit(fastmath=True)(body)


# ----------------------------------------------------------------------------------------- scaling
def scaling(pair: Pair, repeats: int) -> dict[str, Any]:
    """Preset seconds per pair at each size (RubberWhale resampled), and DIS medium for reference."""
    out: dict[str, Any] = {}
    for preset in ("quality", "realtime"):
        method = engine(FlowConfig.preset(preset))
        out[f"flow_node:{preset}"] = {}
        for w, h in SIZES:
            p = resize_pair(pair, (w, h), f"{w}x{h}")
            out[f"flow_node:{preset}"][f"{w}x{h}"] = time_pairs(method, [p], repeats)[p.name]["seconds"]
    return out


def frontier(pairs: list[Pair], repeats: int) -> list[dict[str, Any]]:
    mb = [p for p in pairs if p.name != "RubberWhale_1280x720"]
    out = []
    for kw in FRONTIER:
        cfg = FlowConfig.preset("realtime").replace(**kw)
        per = time_pairs(engine(cfg), mb, repeats)
        out.append({"settings": kw, "mean_seconds": float(np.mean([v["seconds"] for v in per.values()])),
                    "mean_aee": float(np.mean([v["aee"] for v in per.values()]))})
        print(f"  frontier {kw}: {out[-1]['mean_seconds'] * 1e3:.1f} ms, AEE {out[-1]['mean_aee']:.3f}",
              flush=True)
    return out


def plot(table: dict[str, Any], front: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot([f["mean_seconds"] * 1e3 for f in front], [f["mean_aee"] for f in front], "o-", color="tab:blue",
            label="flow_node settings (frontier)")
    for name, r in table.items():
        mine = name.startswith("flow_node")
        ax.plot(r["mean_seconds"] * 1e3, r["mean_aee"], "s" if mine else "^",
                color="tab:blue" if mine else "tab:red")
        ax.annotate(name.replace("flow_node:", "").replace("opencv_", ""), (r["mean_seconds"] * 1e3, r["mean_aee"]),
                    fontsize=7, xytext=(3, 3), textcoords="offset points")
    ax.set_xscale("log")
    ax.set_xlabel("mean time per Middlebury pair (ms, log)")
    ax.set_ylabel("mean AEE (px)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


# ------------------------------------------------------------------------------------------- report
def markdown(res: dict[str, Any]) -> str:
    t = res["middlebury"]
    lines = ["| method | mean ms/pair | mean AEE | x DualTVL1 time | x DIS medium time | 1280x720 ms |",
             "|---|---:|---:|---:|---:|---:|"]
    for name, r in t.items():
        hd = r["per_pair"].get("RubberWhale_1280x720", {}).get("seconds", float("nan"))
        lines.append(f"| {name} | {r['mean_seconds'] * 1e3:.1f} | {r['mean_aee']:.3f} | "
                     f"{r['mean_time_ratio_vs_opencv_dualtvl1']:.4f} | "
                     f"{r['mean_time_ratio_vs_opencv_dis_medium']:.2f} | "
                     f"{hd * 1e3:.1f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--repeats", type=int, default=7, help="timed runs per pair (median), fast methods")
    ap.add_argument("--slow-repeats", type=int, default=5, help="timed runs per pair for DualTVL1 and skimage")
    ap.add_argument("--sequences", nargs="*", default=list(SEQUENCES), help="Middlebury sequences (need RubberWhale)")
    ap.add_argument("--output", type=Path, default=RESULTS / "speed.json")
    args = ap.parse_args(argv)

    pairs = load_middlebury(args.data, tuple(args.sequences))
    whale = next(p for p in pairs if p.name == "RubberWhale")
    pairs.append(resize_pair(whale, (1280, 720), "RubberWhale_1280x720"))
    res: dict[str, Any] = {"command": "python -m bench.speed " + " ".join(argv or sys.argv[1:]),
                           "machine": machine(), "presets": {p: FlowConfig.preset(p).to_dict() for p in PRESETS_TIMED}}
    print("cold start", flush=True)
    res["cold_start"] = {p: cold_start(whale, p) for p in ("realtime", "quality")}
    print("kernel vs floor", flush=True)
    res["kernel"] = kernel_vs_floor()
    print("middlebury + 1280x720", flush=True)
    res["middlebury"] = middlebury_table(pairs, args.repeats, args.slow_repeats)
    print("frontier", flush=True)
    res["frontier"] = frontier(pairs, max(3, args.repeats // 2))
    print("scaling", flush=True)
    res["scaling"] = scaling(whale, max(3, args.repeats // 2))
    write_json(args.output, res)
    plot(res["middlebury"], res["frontier"], args.output.parent.parent / "speed_frontier.png")
    print(markdown(res))
    print(json.dumps({k: res[k] for k in ("cold_start", "kernel", "scaling")}, indent=1))


if __name__ == "__main__":
    main()
