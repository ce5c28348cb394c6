"""quality census on rendered 128x96 scenes like the bags (seed 103, 2 pairs each): mean AEE per setting."""
import numpy as np

from flow_node.bag.synth import SynthSpec, render_frames
from flow_node.core import FlowConfig, FlowEstimator


def aee(f: np.ndarray, g: np.ndarray) -> float:
    return float(np.mean(np.hypot(*(f - g).transpose(2, 0, 1))))


q = FlowConfig.preset("quality").replace(threads=1, photometric="census")
SETTINGS = (("old", dict(census_finest_radius=1, census_delta=0.2, census_alpha=0.045)),
            ("qdelta", dict(census_finest_radius=1, census_delta=0.03, census_alpha=0.16)),
            ("r2d03a16", dict(census_finest_radius=2, census_delta=0.03, census_alpha=0.16)),
            ("r1d05a10", dict(census_finest_radius=1, census_delta=0.05, census_alpha=0.10)),
            ("r2d05a10", dict(census_finest_radius=2, census_delta=0.05, census_alpha=0.10)))
for scene, enc in (("deformation", "mono16"), ("rotation", "mono8"), ("zoom", "rgb8")):
    frames, gts = render_frames(SynthSpec(scene=scene, frames=3, size=(128, 96), encoding=enc, seed=103))
    for name, changes in SETTINGS:
        est = FlowEstimator(q.replace(**changes))
        errors = [aee(est.estimate(frames[k], frames[k + 1]).flow, gts[k]) for k in (0, 1)]
        print(scene, name, round(float(np.mean(errors)), 4))
