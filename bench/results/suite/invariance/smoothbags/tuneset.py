"""Tune set for task smoothbags (issue 25): rendered 128x96 scenes of the bundled bags' kinds, new seeds.

The bags are fixed data, so candidates are scored on these instead. Each scene is rendered exactly as
``flow_bag synth`` renders the bundled bag of that kind (flow_node.bag.synth.render_frames: the same
SynthSpec encoding, noise and brightness as bags/README.md; 6 frames = 5 pairs), with seeds 101-108 (the bags
use 1-5). Frames are delivered as decoded (mono8, mono16, rgb8 arrays), as bench.suite.data.bags does.

    PYTHONPATH=$PWD python bench/results/suite/invariance/smoothbags/tuneset.py NAMES [SCENES [SEEDS]]

NAMES: comma list of candidates (keys of CHANGES); ``grey`` is realtime with its default photometric stage,
every other key realtime census as before this task
(DELTA 0.2, alpha 0.04; the preset now sets census_delta 0.07, census_alpha 0.08) with the change.
Prints mean AEE per scene kind and overall.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from flow_node.bag.synth import SynthSpec, render_frames
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig

# the bundled bags' specs by scene kind (bags/README.md), seed replaced
SPECS = {"translation": dict(encoding="png"), "rotation": dict(encoding="mono8"), "zoom": dict(encoding="rgb8"),
         "deformation": dict(encoding="mono16"), "objects": dict(encoding="mono8", noise=0.01, brightness=0.01)}
RT = FlowConfig.preset("realtime").replace(threads=1)
CEN = RT.replace(photometric="census", census_delta=0.2, census_alpha=0.0)  # census before this task (the runs here)
CHANGES: dict[str, dict[str, object]] = {"grey": {}, "census": {}}


def add(name: str) -> None:
    """Parse a candidate name of the form key=value+key=value into CHANGES (values as FlowConfig's types)."""
    if name in CHANGES:
        return
    kv = dict(p.split("=") for p in name.split("+"))
    CHANGES[name] = {k: type(getattr(CEN, k))(v) for k, v in kv.items()}


def config(name: str) -> FlowConfig:
    """The candidate's configuration."""
    return RT if name == "grey" else CEN.replace(**CHANGES[name])


def pairs(scenes: list[str], seeds: list[int]):  # type: ignore[no-untyped-def]
    """(scene, seed, k, f0, f1, gt) for every consecutive pair of every rendered scene."""
    for scene in scenes:
        for seed in seeds:
            enc = SPECS[scene]
            spec = SynthSpec(scene=scene, frames=6, size=(128, 96), seed=seed, **enc)  # type: ignore[arg-type]
            frames, gts = render_frames(spec)
            for k in range(len(gts)):
                yield scene, seed, k, frames[k], frames[k + 1], gts[k]


def main() -> None:
    names = sys.argv[1].split(",")
    for n in names:
        add(n)
    scenes = sys.argv[2].split(",") if len(sys.argv) > 2 else ["deformation", "rotation", "zoom"]
    seeds = [int(s) for s in sys.argv[3].split(",")] if len(sys.argv) > 3 else list(range(101, 109))
    est = {n: FlowEstimator(config(n)) for n in names}
    aee: dict[str, dict[str, list[float]]] = {n: {} for n in names}
    cpu = {n: 0.0 for n in names}
    for scene, _seed, _k, f0, f1, gt in pairs(scenes, seeds):
        for n, e in est.items():
            t = time.process_time()
            flow = e.estimate(f0, f1).flow
            cpu[n] += time.process_time() - t
            aee[n].setdefault(scene, []).append(float(np.hypot(*np.moveaxis(flow - gt, -1, 0)).mean()))
    print("candidate | " + " | ".join(scenes) + " | mean | cpu s")
    for n in names:
        per = [float(np.mean(aee[n][s])) for s in scenes]
        allv = [a for s in scenes for a in aee[n][s]]
        print(f"{n} | " + " | ".join(f"{p:.4f}" for p in per) + f" | {np.mean(allv):.4f} | {cpu[n]:.2f}", flush=True)


if __name__ == "__main__":
    main()
