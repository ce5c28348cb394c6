import numpy as np
from flow_node.core import FlowConfig, FlowEstimator
from flow_node.bag.synth import SynthSpec, render_frames
def aee(f, g): return float(np.mean(np.hypot(*(f - g).transpose(2, 0, 1))))
q = FlowConfig.preset("quality").replace(threads=1, photometric="census")
for scene, enc in (("deformation", "mono16"), ("rotation", "mono8"), ("zoom", "rgb8")):
    frames, gts = render_frames(SynthSpec(scene=scene, frames=3, size=(128, 96), encoding=enc, seed=103))
    for name, c in (("old", q.replace(census_delta=0.2, census_alpha=0.045)), ("qdelta", q),
                    ("r2only", q.replace(census_finest_radius=2)),
                    ("r1d05a10", q.replace(census_delta=0.05, census_alpha=0.10)),
                    ("r2d05a10", q.replace(census_finest_radius=2, census_delta=0.05, census_alpha=0.10))):
        e = FlowEstimator(c)
        print(scene, name, round(np.mean([aee(e.estimate(frames[k], frames[k + 1]).flow, gts[k]) for k in range(2)]), 4))
