"""``python -m bench.suite.stream_cpu``: the CPU time of a stream preset's predicted frames, for an A/B of two
code versions on a shared machine (run this module alternately from each tree, in fresh processes).

    python -m bench.suite.stream_cpu --size 320x240 --kind pan --repeats 6
    for r in 1 2 3; do for t in /path/main /path/branch; do (cd $t && PYTHONPATH=$t python -m \
        bench.suite.stream_cpu --size 320x240 --kind objects); done; done

One report sequence (``--kind``) is streamed ``--repeats`` + 1 times through ``FlowStream.process`` (as
bench.suite.streams runs it; the first pass warms caches up and is not counted). Each predicted frame's
``time.process_time`` (every thread of the process) is taken; the figure is the mean over the frames of each
frame's minimum over the passes (the least disturbed figure on a loaded machine: a frame's minimum is the
pass in which nothing else ran on its core), beside the median over passes of the per-pass mean. Prints
one line; no file. bench.suite.stream_costs has the per-stage times against DIS.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

from flow_node.core.config import FlowConfig
from flow_node.core.temporal import PREDICTED
from flow_node.pipeline.stream import FlowStream, StreamSettings
from flow_node.process import keep_freed_memory

from ..common import wxh
from .sequences import sequences
from .streams import PERIOD_NS


def cpu_per_frame(preset: str, size: tuple[int, int], kind: str, repeats: int) -> tuple[float, float, int]:
    """(mean of each predicted frame's minimum CPU seconds over ``repeats`` passes, median over passes of the
    pass's mean, predicted frames per pass) of ``preset`` on the report sequence ``kind`` at ``size`` (W, H)."""
    seq = next(iter(sequences("report", size, (kind,))))
    stream = FlowStream(StreamSettings(config=FlowConfig.preset(preset)))
    stream.warmup(size[::-1])
    per_frame: dict[int, list[float]] = {}
    means = []
    for r in range(repeats + 1):
        stream.reset("repeat")
        stream.process(seq.frames[0], PERIOD_NS, "mono8")
        times = []
        for t in range(1, len(seq.frames)):
            cpu = time.process_time()
            out = stream.process(seq.frames[t], (t + 1) * PERIOD_NS, "mono8")
            cpu = time.process_time() - cpu
            if r and out is not None and out.stats.stream == PREDICTED:
                per_frame.setdefault(t, []).append(cpu)
                times.append(cpu)
        if r:
            means.append(float(np.mean(times)))
    return float(np.mean([min(v) for v in per_frame.values()])), float(np.median(means)), len(per_frame)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", default="320x240", help="WxH")
    ap.add_argument("--kind", default="pan", help="report sequence kind (bench.suite.sequences.KINDS)")
    ap.add_argument("--preset", default="stream_fast")
    ap.add_argument("--repeats", type=int, default=6)
    args = ap.parse_args(argv)
    w, h = wxh(args.size)
    keep_freed_memory()  # as the node's main() and bench.suite.streams do
    load = f"{os.getloadavg()[0]:.2f}"
    best, median, n = cpu_per_frame(args.preset, (w, h), args.kind, args.repeats)
    print(f"{args.preset} {w}x{h} {args.kind}: CPU ms per predicted frame {1e3 * best:.3f} (per-frame min over "
          f"{args.repeats} passes), {1e3 * median:.3f} (median pass); {n} frames; load {load}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
