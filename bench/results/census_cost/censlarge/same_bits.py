"""Throwaway (task censlarge): the census kernels' outputs on random and textured levels of several shapes, radius 1 and
2, grey and 3 channels, L1 and L2 -- saved (``save PATH``) or compared bit for bit with a saved file (``check PATH``).
``--more``: also the levels fastest's small frames solve (32-80 px wide, vector loops' remainders; task fastcens).
PYTHONPATH=. python bench/results/census_cost/censlarge/same_bits.py save|check PATH [--more]"""
from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np

from flow_node.core import numba_census as nc
from flow_node.core.census import CENSUS
from flow_node.core.numba_backend import WARPER

SHAPES = ((1, 1), (2, 3), (5, 4), (17, 23), (47, 155), (120, 160), (240, 320))
MORE = ((9, 33), (24, 32), (30, 40), (48, 64), (60, 80), (97, 146))


def outputs(shapes: tuple[tuple[int, int], ...] = SHAPES) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(5)
    out = {}
    for h, w in shapes:
        for n_c in (1, 3):
            f0 = rng.random((n_c, h, w), dtype=np.float32)
            f1 = np.clip(f0 + 0.05 * rng.standard_normal((n_c, h, w)).astype(np.float32), 0, 1)
            flow = (2.0 * rng.standard_normal((2, h, w))).astype(np.float32)
            for radius in (1, 2):
                params = replace(CENSUS, radius=radius, eps=0.02, delta=0.07)
                lvl = nc.level_signature_numba(f0, params)[0].copy()
                out[f"level_{h}x{w}_{n_c}_{radius}"] = lvl
                out[f"planes_{h}x{w}_{n_c}_{radius}"] = nc.census_planes_numba(f0[0], params)
                coefs = WARPER.coefficients(f1, "bspline")
                for robust in (True, False):
                    out[f"form_{h}x{w}_{n_c}_{radius}_{robust}"] = nc.census_form_numba(
                        lvl, None, coefs, f1, flow, "bspline", robust, params)
    return out


def main() -> None:
    mode, path = sys.argv[1], sys.argv[2]
    got = outputs(SHAPES + MORE if "--more" in sys.argv[3:] else SHAPES)
    if mode == "save":
        np.savez_compressed(path, **got)
        print(f"saved {len(got)} arrays")
        return
    ref = np.load(path)
    bad = [k for k in ref.files if not np.array_equal(ref[k], got[k], equal_nan=True)]
    print(f"{len(ref.files) - len(bad)} of {len(ref.files)} arrays the same bit for bit; differ: {bad}")


if __name__ == "__main__":
    main()
