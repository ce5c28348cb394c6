"""``python -m bench.suite.stream_costs``: where a stream preset's time per frame goes, against OpenCV DIS
ultrafast on the same frames (issue 26), or with ``--cpu`` the CPU time of its predicted frames alone, for an A/B
of two code versions on a shared machine; what each figure is: docs/suite.md, "Streams".

    python -m bench.suite.stream_costs --size 320x240 --method lite=stream_lite[,key=value...] [--out DIR]
    python -m bench.suite.stream_costs --cpu --size 320x240 --kind pan --repeats 6   # stream_fast by default
    for r in 1 2 3; do for t in /path/main /path/branch; do
        (cd $t && PYTHONPATH=$t python -m bench.suite.stream_costs --cpu --kind objects); done; done
"""

from __future__ import annotations

import argparse
import os
import time
from collections import defaultdict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from flow_node.core import api, numba_backend, numba_census, refine, temporal
from flow_node.core.config import FlowConfig
from flow_node.pipeline.stream import FlowStream, StreamSettings
from flow_node.process import keep_freed_memory

from ..common import machine, md_table, run_record, write_result, wxh
from .sequences import Sequence, sequences
from .streams import PERIOD_NS, parse_method

# (module, function, label): the stages timed; the refinement's parts are indented under it (the grey-value
# linearisation, or the census term's: a level's setup -- frame 0's signatures, frame 1's coefficients, the
# contrasts -- and the per-warp form kernel, which numba_census.census_form_numba looks up by its global name)
STAGES = ((temporal, "photometric_stage", "photometric stage"), (temporal, "make_pyramid", "pyramid"),
          (temporal, "predict", "prediction (splat, holes)"), (temporal, "predicted_cost", "prediction check"),
          (temporal, "refine_prediction", "refinement"), (numba_backend, "linearise_numba", "  linearisation"),
          (refine, "census_problem", "  census level setup"), (numba_census, "census_kernel", "  census forms"),
          (numba_backend, "solve_numba", "  solver iterations"), (refine, "median_filter", "  median filter"),
          (api, "interleaved_flow", "upsampling to the input grid"),
          (api, "unexplained_of", "result check (unexplained)"))


@contextmanager
def timed_stages(acc: dict[str, float]) -> Iterator[None]:
    """Wrap every STAGES function so that its wall-clock seconds add to ``acc[label]``; restored on exit.
    Backends resolve their kernels when built: build the stream inside the block."""
    saved = [(mod, name, getattr(mod, name)) for mod, name, _ in STAGES]

    def wrap(fn: Callable[..., Any], label: str) -> Callable[..., Any]:
        def timed(*args: Any, **kwargs: Any) -> Any:
            start = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                acc[label] += time.perf_counter() - start
        return timed

    try:
        for (mod, name, label), (_, _, fn) in zip(STAGES, saved, strict=True):
            setattr(mod, name, wrap(fn, label))
        yield
    finally:
        for mod, name, fn in saved:
            setattr(mod, name, fn)


def stream_passes(config: FlowConfig, seq: Sequence, repeats: int, before: Callable[[], None] = lambda: None
                  ) -> Iterator[tuple[int, int, bool, float, float]]:
    """Stream ``seq`` 1 + ``repeats`` times (pass 0 warms up) through a FlowStream with ``config``, built on
    the first step; per frame t >= 1 (``before()`` called just before it) yield (pass, t, whether the stream
    predicted it, its wall seconds, its CPU seconds)."""
    stream = FlowStream(StreamSettings(config=config))
    stream.warmup(seq.frames[0].shape)
    for r in range(repeats + 1):
        stream.reset("repeat")
        stream.process(seq.frames[0], PERIOD_NS, "mono8")
        for t in range(1, len(seq.frames)):
            before()
            start, cpu = time.perf_counter(), time.process_time()
            out = stream.process(seq.frames[t], (t + 1) * PERIOD_NS, "mono8")
            seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
            yield r, t, out is not None and out.stats.stream == temporal.PREDICTED, seconds, cpu


def measure(method: str, size: tuple[int, int], repeats: int) -> dict[str, Any]:
    """Per-stage ms per frame of ``method`` (NAME=PRESET[,key=value...]) and DIS ultrafast's, medians over
    ``repeats`` passes over the tune split's pan sequence at ``size`` (W, H)."""
    name, config = parse_method(method)
    seq = next(iter(sequences("tune", size, ("pan",))))
    dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST)
    acc: dict[str, float] = defaultdict(float)
    dis_s: dict[int, list[float]] = defaultdict(list)
    frames: dict[int, list[tuple[float, float, dict[str, float]]]] = defaultdict(list)  # the predicted ones
    with timed_stages(acc):
        for r, t, predicted, seconds, cpu in stream_passes(config, seq, repeats, acc.clear):
            start = time.perf_counter()
            dis.calc(seq.frames[t - 1], seq.frames[t], None)
            dis_s[r].append(time.perf_counter() - start)
            if predicted:  # the stream stage's frames only
                frames[r].append((seconds, cpu, dict(acc)))
    passes = [{"frame": float(np.mean([f[0] for f in frames[r]])), "cpu": float(np.mean([f[1] for f in frames[r]])),
               "dis": float(np.median(dis_s[r])), "predicted": len(frames[r]),
               "stages": {k: sum(f[2].get(k, 0.0) for f in frames[r]) / len(frames[r])
                          for k in dict.fromkeys(k for f in frames[r] for k in f[2])}} for r in range(1, repeats + 1)]
    frame, cpu, dis_median = (float(np.median([p[k] for p in passes])) for k in ("frame", "cpu", "dis"))
    stages = {label: float(np.median([p["stages"].get(label, 0.0) for p in passes])) for _, _, label in STAGES}
    top = sum(v for k, v in stages.items() if not k.startswith(" "))
    stages["other"] = max(frame - top, 0.0)
    return {"method": name, "config": config.to_dict(), "size": list(size), "repeats": repeats,
            "frame_seconds": frame, "frame_cpu_seconds": cpu, "dis_ultrafast_seconds": dis_median, "stages": stages,
            "predicted": min(p["predicted"] for p in passes), "pairs": len(seq.frames) - 1}


def cpu_per_frame(method: str, size: tuple[int, int], kind: str, repeats: int) -> tuple[float, float, int]:
    """(mean of each predicted frame's minimum CPU seconds over ``repeats`` passes, median over passes of the
    pass's mean, predicted frames per pass) of ``method`` (NAME=PRESET[,key=value...]) on the report sequence
    ``kind`` at ``size`` (W, H)."""
    seq = next(iter(sequences("report", size, (kind,))))
    per_frame: dict[int, list[float]] = {}
    per_pass: dict[int, list[float]] = defaultdict(list)
    for r, t, predicted, _, cpu in stream_passes(parse_method(method)[1], seq, repeats):
        if r and predicted:
            per_frame.setdefault(t, []).append(cpu)
            per_pass[r].append(cpu)
    return (float(np.mean([min(v) for v in per_frame.values()])),
            float(np.median([np.mean(v) for v in per_pass.values()])), len(per_frame))


def markdown(results: list[dict[str, Any]], command: str, load: str) -> str:
    """One table per method: ms per frame and x DIS ultrafast per stage."""
    lines = ["# Stream stage costs per frame (tune split, pan)", "", f"`{command}`", "", f"Load: {load}", ""]
    for res in results:
        d = res["dis_ultrafast_seconds"]
        w, h = res["size"]
        lines += [f"## {res['method']} at {w}x{h}: {1e3 * res['frame_seconds']:.2f} ms per frame = "
                  f"{res['frame_seconds'] / d:.2f}x DIS ultrafast ({1e3 * d:.2f} ms), CPU time "
                  f"{1e3 * res.get('frame_cpu_seconds', float('nan')):.2f} ms; "
                  f"{res['predicted']} / {res['pairs']} pairs predicted", "",
                  *md_table(["stage", "ms per frame", "x DIS ultrafast"],
                            [[label.replace("  ", "- "), f"{1e3 * s:.3f}", f"{s / d:.2f}"]
                             for label, s in res["stages"].items()]), ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.suite.stream_costs", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", default="320x240", help="WIDTHxHEIGHT")
    ap.add_argument("--method", action="append", default=[], metavar="NAME=PRESET[,key=value...]",
                    help="default stream_lite (--cpu: stream_fast)")
    ap.add_argument("--repeats", type=int, default=None, help="passes counted (default 5; --cpu: 6)")
    ap.add_argument("--out", type=Path, default=None, help="directory for costs_<size>.{json,md}")
    ap.add_argument("--cpu", action="store_true", help="only the CPU time per predicted frame: one line per method")
    ap.add_argument("--kind", default="pan", help="--cpu: the report sequence (bench.suite.sequences.KINDS)")
    args = ap.parse_args(argv)
    keep_freed_memory()  # as the node's main() does: arrays freed by one frame serve the next
    w, h = wxh(args.size)
    if args.cpu:
        load, repeats = f"{os.getloadavg()[0]:.2f}", args.repeats or 6
        for m in args.method or ["stream_fast=stream_fast"]:
            best, median, n = cpu_per_frame(m, (w, h), args.kind, repeats)
            print(f"{parse_method(m)[0]} {w}x{h} {args.kind}: CPU ms per predicted frame {1e3 * best:.3f} (per-frame "
                  f"min over {repeats} passes), {1e3 * median:.3f} (median pass); {n} frames; load {load}")
        return 0
    results = [measure(m, (w, h), args.repeats or 5) for m in (args.method or ["stream_lite=stream_lite"])]
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg()) + " (1, 5, 15 min)"
    command = run_record("bench.suite.stream_costs", argv)["command"]
    md = markdown(results, command, load)
    res = {"command": command, "load": load, "machine": machine(), "results": results}
    write_result(args.out and args.out / f"costs_{w}x{h}", res, md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
