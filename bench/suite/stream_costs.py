"""``python -m bench.suite.stream_costs --size 320x240 --method lite=stream_lite[,key=value...] [--out DIR]``:
where a stream preset's time per frame goes, against OpenCV DIS ultrafast on the same frames (issue 26: a
stream preset at <= 2x DIS ultrafast's time). The tune pan is streamed 1 + ``--repeats`` times; every stage
the stream stage calls (STAGES) is timed by wrapping its function, per predicted frame, with the frame's wall
and CPU time and DIS ultrafast right after it; medians over the repeats (docs/suite.md, "Streams").
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

from flow_node.core import api, numba_backend, refine, temporal
from flow_node.pipeline.stream import FlowStream, StreamSettings
from flow_node.process import keep_freed_memory

from ..common import machine, run_record, write_result, wxh
from .sequences import sequences
from .streams import PERIOD_NS, parse_method

# (module, function, label): the stages timed; the refinement's parts are indented under it
STAGES = ((temporal, "photometric_stage", "photometric stage"), (temporal, "make_pyramid", "pyramid"),
          (temporal, "predict", "prediction (splat, holes)"), (temporal, "predicted_cost", "prediction check"),
          (temporal, "refine_prediction", "refinement"), (numba_backend, "linearise_numba", "  linearisation"),
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


def measure(method: str, size: tuple[int, int], repeats: int) -> dict[str, Any]:
    """Per-stage ms per frame of ``method`` (NAME=PRESET[,key=value...]) and DIS ultrafast's, medians over
    ``repeats`` passes over the tune split's pan sequence at ``size`` (W, H)."""
    name, config = parse_method(method)
    seq = next(iter(sequences("tune", size, ("pan",))))
    dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST)
    acc: dict[str, float] = defaultdict(float)
    passes = []
    with timed_stages(acc):
        stream = FlowStream(StreamSettings(config=config))
        stream.warmup(size[::-1])
        for r in range(repeats + 1):  # the first pass warms caches up, not counted
            stream.reset("repeat")
            stream.process(seq.frames[0], PERIOD_NS, "mono8")
            frame_s, cpu_s, dis_s, totals = [], [], [], defaultdict(float)
            for t in range(1, len(seq.frames)):
                acc.clear()
                start, cpu = time.perf_counter(), time.process_time()
                out = stream.process(seq.frames[t], (t + 1) * PERIOD_NS, "mono8")
                seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
                start = time.perf_counter()
                dis.calc(seq.frames[t - 1], seq.frames[t], None)
                dis_s.append(time.perf_counter() - start)
                if out is not None and out.stats.stream == temporal.PREDICTED:  # the stream stage's frames only
                    frame_s.append(seconds)
                    cpu_s.append(cpu)
                    for k, v in acc.items():
                        totals[k] += v
            if r:
                n = len(frame_s)
                passes.append({"frame": float(np.mean(frame_s)), "cpu": float(np.mean(cpu_s)),
                               "dis": float(np.median(dis_s)),
                               "stages": {k: v / n for k, v in totals.items()}, "predicted": n})
    frame, cpu, dis_median = (float(np.median([p[k] for p in passes])) for k in ("frame", "cpu", "dis"))
    stages = {label: float(np.median([p["stages"].get(label, 0.0) for p in passes])) for _, _, label in STAGES}
    top = sum(v for k, v in stages.items() if not k.startswith(" "))
    stages["other"] = max(frame - top, 0.0)
    return {"method": name, "config": config.to_dict(), "size": list(size), "repeats": repeats,
            "frame_seconds": frame, "frame_cpu_seconds": cpu, "dis_ultrafast_seconds": dis_median, "stages": stages,
            "predicted": min(p["predicted"] for p in passes), "pairs": len(seq.frames) - 1}


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
                  "| stage | ms per frame | x DIS ultrafast |", "|---|---|---|"]
        for label, s in res["stages"].items():
            lines.append(f"| {label.replace('  ', '- ')} | {1e3 * s:.3f} | {s / d:.2f} |")
        lines.append("")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.suite.stream_costs", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", default="320x240", help="WIDTHxHEIGHT")
    ap.add_argument("--method", action="append", default=[], metavar="NAME=PRESET[,key=value...]")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", type=Path, default=None, help="directory for costs_<size>.{json,md}")
    args = ap.parse_args(argv)
    keep_freed_memory()  # as the node's main() does: arrays freed by one frame serve the next
    w, h = wxh(args.size)
    results = [measure(m, (w, h), args.repeats) for m in (args.method or ["stream_lite=stream_lite"])]
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg()) + " (1, 5, 15 min)"
    command = run_record("bench.suite.stream_costs", argv)["command"]
    md = markdown(results, command, load)
    res = {"command": command, "load": load, "machine": machine(), "results": results}
    write_result(args.out and args.out / f"costs_{w}x{h}", res, md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
