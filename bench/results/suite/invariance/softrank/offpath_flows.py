"""Flows of a few presets on a rendered pair (grey and colour), saved to argv[1] (.npz)."""
import sys
import numpy as np
from flow_node.bag.synth import SynthSpec, render_frames
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig
out = {}
for enc in ("mono8", "rgb8"):
    frames, _ = render_frames(SynthSpec(scene="rotation", frames=2, size=(160, 120), encoding=enc, seed=5))
    for p in ("realtime", "quality", "fastest", "stream_fast"):
        cfg = FlowConfig.preset(p).replace(threads=2)
        if enc == "rgb8":
            cfg = cfg.replace(colour="channels")
        out[f"{p}-{enc}"] = FlowEstimator(cfg).estimate(frames[0], frames[1]).flow
np.savez(sys.argv[1], **out)
