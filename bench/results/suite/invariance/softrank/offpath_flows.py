"""Task softrank's off-path check: flows of four presets on a rendered 160x120 rotation pair, grey (mono8) and
colour (rgb8, ``colour: channels``), saved to argv[1] (.npz). Run once with main on PYTHONPATH and once with
the branch (each with its own NUMBA_CACHE_DIR) and compare the arrays: equal bit for bit (summary.md)."""

from __future__ import annotations

import sys

import numpy as np

from flow_node.bag.synth import SynthSpec, render_frames
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig


def main() -> None:
    out: dict[str, np.ndarray] = {}
    for enc in ("mono8", "rgb8"):
        frames, _ = render_frames(SynthSpec(scene="rotation", frames=2, size=(160, 120), encoding=enc, seed=5))
        for p in ("realtime", "quality", "fastest", "stream_fast"):
            cfg = FlowConfig.preset(p).replace(threads=2)
            if enc == "rgb8":
                cfg = cfg.replace(colour="channels")
            out[f"{p}-{enc}"] = FlowEstimator(cfg).estimate(frames[0], frames[1]).flow
    np.savez(sys.argv[1], **out)


if __name__ == "__main__":
    main()
