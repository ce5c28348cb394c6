"""Flows of census_radius 1 (the default) on this tree against another tree's: are they bit-identical?

    PYTHONPATH=<tree> python same_flows.py save OUT.npz      (run once per tree)
    python same_flows.py compare A.npz B.npz

Every Middlebury pair (grey; realtime, fastest, quality census at alpha 0.045, and realtime grey values) and
the RGB pairs with colour channels (realtime census), numba backend, one thread."""
from __future__ import annotations

import sys

import numpy as np


def save(out: str) -> None:
    from bench.suite import data
    from flow_node.core.api import FlowEstimator
    from flow_node.core.config import FlowConfig
    runs = {"realtime_census": FlowConfig.preset("realtime").replace(photometric="census", threads=1),
            "fastest_census": FlowConfig.preset("fastest").replace(photometric="census", threads=1),
            "quality_census": FlowConfig.preset("quality").replace(photometric="census", alpha=0.045, threads=1),
            "realtime_grey": FlowConfig.preset("realtime").replace(threads=1),
            "realtime_census_rgb": FlowConfig.preset("realtime").replace(photometric="census", colour="channels",
                                                                         threads=1)}
    from bench.common import DEFAULT_DATA
    from flow_node.core.flowio import read_image
    flows = {}
    for s in data.middlebury(False):
        rgb = [read_image(DEFAULT_DATA / s.name / f"frame1{k}.png") for k in (0, 1)]
        for name, cfg in runs.items():
            a, b = rgb if name.endswith("rgb") else (s.f0, s.f1)
            flows[f"{s.name}/{name}"] = FlowEstimator(cfg).estimate(a, b).flow
    np.savez(out, **flows)


def compare(a: str, b: str) -> None:
    fa, fb = np.load(a), np.load(b)
    same = [k for k in fa.files if np.array_equal(fa[k], fb[k])]
    print(f"{len(same)} of {len(fa.files)} flows bit-identical")
    for k in fa.files:
        if k not in same:
            print(k, float(np.abs(fa[k] - fb[k]).max()))


if __name__ == "__main__":
    save(sys.argv[2]) if sys.argv[1] == "save" else compare(sys.argv[2], sys.argv[3])
