"""Task lownoise: frame 0's signatures at its own noise floor (EPS from frame 0's noise std, census_noise.pair_noise's
frames[0]) while frame 1's keep the pair's (the larger std's), by monkeypatch on refine.census_problem; a screen on the
tune split's unchanged and sensor_noise pairs (sweep.py's regimes).

    python bench/results/suite/invariance/lownoise/eps0.py PRESET OUT.json
"""

import sys

import numpy as np

from flow_node.core import engine, refine

_make_pyramid = engine.make_pyramid
NOISE = {"pair": None}


def make_pyramid(*a, **k):
    NOISE["pair"] = k.get("noise")
    return _make_pyramid(*a, **k)


def census_problem(c0, c1, cfg, backend, robust, eps_floor=0.0, finest=False, g=None, memo=None):
    coefs = backend.warper.coefficients(c1, cfg.warp_kernel)
    contrast = refine.level_contrast(c0, c1, cfg, backend.contrast, memo)
    params = refine.level_census(cfg, c0.shape[2], eps_floor, contrast, finest)
    noise = NOISE["pair"]
    ratio = noise.frames[0] / noise.sigma if noise is not None and noise.frames and noise.sigma > 0 else 1.0
    params0 = refine.level_census(cfg, c0.shape[2], eps_floor * ratio, contrast, finest)
    f0, g0 = backend.signature(c0, params0)
    h, w = c0.shape[1:]
    a, c = np.zeros((2, h, w), np.float32), np.zeros((h, w), np.float32)
    form = np.empty((5, h, w), np.float32)

    def around(v0):
        return refine.Problem(a, c, q=backend.census_form(f0, g0, coefs, c1, v0, cfg.warp_kernel, robust, params,
                                                           out=form), g=g)

    return around


engine.make_pyramid, refine.census_problem = make_pyramid, census_problem
sys.path.insert(0, "bench/results/suite/invariance/lownoise")
import sweep  # noqa: E402

sweep.main()
