"""Throwaway (task censlarge): per data set and preset, grey (normalise) and census, the whole call's process CPU time
(time.process_time: every thread of the process), the calling thread's CPU time (time.thread_time) and the wall clock
(ms summed over the pairs, median of the rounds, terms interleaved). What process - thread is: other threads' CPU time
(OpenCV's worker pool after a parallel call: DIS, the photometric stage) charged to the call.
PYTHONPATH=. python bench/results/census_cost/censlarge/clocks.py large|fine_320|middlebury realtime,fastest ROUNDS"""
from __future__ import annotations

import statistics
import sys
import time

import cv2

from bench.suite import data as sdata
from bench.suite import synthetic
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig

DATA = {"large": lambda: sdata.large(False), "middlebury": lambda: sdata.middlebury(False),
        "fine_320": lambda: list(synthetic.fine("tune", False, (320, 240)))}


def main() -> None:
    which, presets, rounds = sys.argv[1], sys.argv[2].split(","), int(sys.argv[3])
    if len(sys.argv) > 4:
        cv2.setNumThreads(int(sys.argv[4]))
    samples = DATA[which]()
    print(f"## {which}: ms summed over {len(samples)} pairs, median of {rounds} rounds; cv2 threads "
          f"{cv2.getNumThreads()}\n")
    print("| preset | term | process | thread | wall | process - thread |")
    print("|---|---|---:|---:|---:|---:|")
    for preset in presets:
        ests = {t: FlowEstimator(FlowConfig.preset(preset).replace(threads=1).with_overrides([f"photometric={t}"]))
                for t in ("normalise", "census")}
        for s in samples:
            for e in ests.values():
                e.estimate(s.f0, s.f1)
        rows = {t: [] for t in ests}
        for r in range(rounds):
            acc = {t: [0.0, 0.0, 0.0] for t in ests}
            for k, s in enumerate(samples):
                for t in (tuple(ests) if (k + r) % 2 == 0 else tuple(ests)[::-1]):
                    a, b, c = time.process_time(), time.thread_time(), time.perf_counter()
                    ests[t].estimate(s.f0, s.f1)
                    x = acc[t]
                    x[0] += time.process_time() - a
                    x[1] += time.thread_time() - b
                    x[2] += time.perf_counter() - c
            for t in ests:
                rows[t].append(acc[t])
        for t in ests:
            p, th, w = (statistics.median(r[i] for r in rows[t]) for i in range(3))
            print(f"| {preset} | {t} | {1e3 * p:.1f} | {1e3 * th:.1f} | {1e3 * w:.1f} | {1e3 * (p - th):.1f} |")
        g, c = rows["normalise"], rows["census"]
        ratios = [statistics.median(b[i] / a[i] for a, b in zip(g, c, strict=True)) for i in range(3)]
        print(f"| {preset} | census / grey | {ratios[0]:.2f}x | {ratios[1]:.2f}x | {ratios[2]:.2f}x | |")
    print()


if __name__ == "__main__":
    main()
