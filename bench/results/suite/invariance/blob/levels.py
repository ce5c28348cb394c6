"""One-off (task blob): per pyramid level of fastest census, the median 3x3 contrast of both frames of a suite
pair (frame 2 under the illumination blob; frames mapped to their 2nd-98th percentiles, roughly as the photometric
stage does) and the noise floor. Usage: python levels.py SEED ... (the pair of seed s has index s % 1000)."""
from __future__ import annotations

import sys

import numpy as np

from bench.suite import photometric as ph
from bench.suite import synthetic
from bench.suite.synthetic import quantise
from flow_node.bag.scenes import render_grey_pair
from flow_node.core.census import OFFSETS, shifted
from flow_node.core.config import FlowConfig
from flow_node.core.pyramid import make_pyramid


def norm(x: np.ndarray) -> np.ndarray:
    """x mapped to its 2nd-98th percentiles, float32."""
    lo, hi = np.percentile(x, [2, 98])
    return ((x - lo) / (hi - lo)).astype(np.float32)


cfg = FlowConfig.preset("fastest").with_overrides(["photometric=census"])
for seed in map(int, sys.argv[1:]):
    scene, name = synthetic.scene_for(seed % 1000, seed, ph.SIZE, span=ph.SPAN)
    i0, i1, gt = render_grey_pair(scene)
    j1 = ph.FAMILIES["illumination"][2](i1, seed)
    print(f"s{seed} {name} gt max {np.hypot(gt[..., 0], gt[..., 1]).max():.2f} px")
    a, b = (norm(quantise(x, 8).astype(np.float32) / 255) for x in (i0, j1))
    pyr = make_pyramid(a, b, cfg)
    for lvl, (x, y) in enumerate(zip(pyr.i0, pyr.i1, strict=True)):
        s = [np.sqrt(np.mean([(shifted(z, dy, dx) - z) ** 2 for dy, dx in OFFSETS], axis=0)) for z in (x, y)]
        print(f"  L{lvl} {x.shape} median s: frame 1 {np.median(s[0]):.4f}, frame 2 (blob) {np.median(s[1]):.4f}; "
              f"noise floor {pyr.eps_floor(lvl):.4f}")
