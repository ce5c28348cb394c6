"""Tune set for task fastbags (issue 25): task fastdelta's (git show
4983857:bench/results/suite/invariance/fastdelta/tuneset.py: smoothbags' rendered scenes with ``fastest``), its
``census`` now fastest census as fastdelta left it (census_delta 0.05, census_alpha 0.2).

Scenes rendered exactly as ``flow_bag synth`` renders the bundled bags (flow_node.bag.synth.render_frames, the
bags' encodings, noise and brightness), 128x96, 6 frames (5 pairs), seeds 101-108 (the bags use 1-5).

    PYTHONPATH=$PWD python bench/results/suite/invariance/fastbags/tuneset.py NAMES [SCENES [SEEDS]]

NAMES: comma list; ``grey`` is fastest with grey values, ``census`` fastest census as task fastdelta left it
(census_delta 0.05, census_alpha 0.2; fastbags' base), ``key=value+key=value`` that census with FlowConfig changes.
Prints the mean AEE per scene kind, overall, and the CPU seconds.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from flow_node.bag.synth import SynthSpec, render_frames
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig

SPECS = {"translation": dict(encoding="png"), "rotation": dict(encoding="mono8"), "zoom": dict(encoding="rgb8"),
         "deformation": dict(encoding="mono16"), "objects": dict(encoding="mono8", noise=0.01, brightness=0.01)}
FAST = FlowConfig.preset("fastest").replace(threads=1)
CEN = FAST.replace(photometric="census", census_delta=0.05, census_alpha=0.2)


def config(name: str) -> FlowConfig:
    """The candidate's configuration (values cast to FlowConfig's field types)."""
    if name == "grey":
        return FAST
    if name == "census":
        return CEN
    kv = dict(p.split("=") for p in name.split("+"))
    return CEN.replace(**{k: type(getattr(CEN, k))(v) for k, v in kv.items()})


def main() -> None:
    names = sys.argv[1].split(",")
    scenes = sys.argv[2].split(",") if len(sys.argv) > 2 else ["deformation", "rotation", "zoom"]
    seeds = [int(s) for s in sys.argv[3].split(",")] if len(sys.argv) > 3 else list(range(101, 109))
    est = {n: FlowEstimator(config(n)) for n in names}
    aee: dict[str, dict[str, list[float]]] = {n: {s: [] for s in scenes} for n in names}
    cpu = dict.fromkeys(names, 0.0)
    for scene in scenes:
        for seed in seeds:
            spec = SynthSpec(scene=scene, frames=6, size=(128, 96), seed=seed, **SPECS[scene])  # type: ignore[arg-type]
            frames, gts = render_frames(spec)
            for k, gt in enumerate(gts):
                for n, e in est.items():
                    t = time.process_time()
                    flow = e.estimate(frames[k], frames[k + 1]).flow
                    cpu[n] += time.process_time() - t
                    aee[n][scene].append(float(np.hypot(*np.moveaxis(flow - gt, -1, 0)).mean()))
    print("candidate | " + " | ".join(scenes) + " | mean | cpu s")
    for n in names:
        per = [float(np.mean(aee[n][s])) for s in scenes]
        print(f"{n} | " + " | ".join(f"{p:.4f}" for p in per) + f" | {float(np.mean(per)):.4f} | {cpu[n]:.2f}",
              flush=True)


if __name__ == "__main__":
    main()
