"""One-off monkeypatch (task blob): a content-adaptive coarse EPS instead of a width threshold -- a level whose
median 3x3 neighbour RMS (the smaller of the two frames') is below THRESH gets EPS >= EPS_EMPTY. Run as
``python adaptive.py THRESH EPS_EMPTY -m bench.suite ...`` or ``... diag.py ...``."""
from __future__ import annotations

import runpy
import sys

import numpy as np

from flow_node.core import refine
from flow_node.core.census import OFFSETS, shifted

THRESH, EPS_EMPTY = float(sys.argv[1]), float(sys.argv[2])
orig = refine.census_problem


def median_rms(img: np.ndarray) -> float:
    """Median over pixels of the RMS of the 8 neighbour differences of img (h, w)."""
    return float(np.median(np.sqrt(np.mean([(shifted(img, dy, dx) - img) ** 2 for dy, dx in OFFSETS], axis=0))))


def patched(c0, c1, cfg, backend, robust, eps_floor=0.0):  # type: ignore[no-untyped-def]
    if min(median_rms(c0[0]), median_rms(c1[0])) < THRESH:
        eps_floor = max(eps_floor, EPS_EMPTY)
    return orig(c0, c1, cfg, backend, robust, eps_floor)


refine.census_problem = patched
rest = sys.argv[3:]
if rest[0] == "-m":
    sys.argv = [rest[1]] + rest[2:]
    runpy.run_module(rest[1], run_name="__main__", alter_sys=True)
else:
    sys.argv = rest
    runpy.run_path(rest[0], run_name="__main__")
