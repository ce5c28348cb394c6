"""Exploration only (task smoothbags; not in the engine): realtime census with each warp's quadratic form
scaled per pixel by theta = clip((KAPPA / (tr T + ZETA))**P, 1/CAP, CAP), a constraint normalisation of the
census term's stiffness tr T (a smooth texture's signature moves little: small T). STATS=1 prints the median
tr T of each finest level instead.

    PYTHONPATH=$PWD KAPPA=.. ZETA=.. P=.. CAP=.. python .../stiffness.py NAMES [SCENES [SEEDS]]   (as tuneset.py)
"""

from __future__ import annotations

import os
import sys
from dataclasses import replace

import numpy as np

from flow_node.core import refine
from flow_node.core.models import weight_quadratic

KAPPA, ZETA = float(os.environ.get("KAPPA", "0.01")), float(os.environ.get("ZETA", "0.001"))
P, CAP, STATS = float(os.environ.get("P", "1")), float(os.environ.get("CAP", "4")), os.environ.get("STATS")
_orig = refine.census_problem


def _patched(c0, c1, cfg, backend, robust, eps_floor=0.0, finest=False):  # type: ignore[no-untyped-def]
    lin = _orig(c0, c1, cfg, backend, robust, eps_floor, finest)

    def around(v0):  # type: ignore[no-untyped-def]
        p = lin(v0)
        tr = p.q[0] + p.q[2]
        if STATS:
            if finest:
                print(f"  finest {c0.shape[1:]} median trT {np.median(tr):.4g} p10 {np.percentile(tr, 10):.3g}")
            return p
        theta = np.clip((KAPPA / (tr + ZETA)) ** P, 1.0 / CAP, CAP).astype(np.float32)
        return replace(p, q=weight_quadratic(p.q, theta))

    return around


refine.census_problem = _patched
sys.path.insert(0, os.path.dirname(__file__))
from tuneset import main  # noqa: E402

if __name__ == "__main__":
    main()
