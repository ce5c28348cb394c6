"""One-off (task censreg): CPU time per census_form_numba call on fixed inputs, per level size, one thread.

    PYTHONPATH=<tree> NUMBA_CACHE_DIR=<tree>/.numba_cache python bench/results/census_cost/censreg/micro.py

Grove2-like input: the first quick Middlebury pair, area-resized to the level sizes of `fastest` (half size) and
`realtime`; flow v0 = (0.7, -0.3) px, Keys kernel, L1 (robust), DELTA 0.05. Prints the median over 7 repeats of
the CPU time per call over the level's pixels (ns/px) and the form's sum (the same in every tree up to the last
digit). Works on every tree since census5 (level_signature_numba and census_form_numba kept their signatures).
"""

from __future__ import annotations

import time
from dataclasses import replace

import cv2
import numba
import numpy as np

from bench.suite.data import middlebury
from flow_node.core import numba_census as nc
from flow_node.core.census import CENSUS

numba.set_num_threads(1)
SIZES = ((584, 388, 25), (292, 194, 100), (146, 97, 300), (73, 48, 1000), (36, 24, 3000))  # w, h, calls


def main() -> None:
    """Print one line: ns/px and the form's sum per level size."""
    s = middlebury(True)[0]
    f0, f1 = (np.asarray(f, np.float32) / (255 if f.dtype == np.uint8 else 1) for f in (s.f0, s.f1))
    res = []
    for w, h, n in SIZES:
        a, b = (cv2.resize(f, (w, h), interpolation=cv2.INTER_AREA)[None].copy() for f in (f0, f1))
        v = np.zeros((2, h, w), np.float32)
        v[0], v[1] = 0.7, -0.3
        params = replace(CENSUS, delta=0.05)
        level, _ = nc.level_signature_numba(a, params)
        out = np.empty((5, h, w), np.float32)
        for _ in range(20):
            nc.census_form_numba(level, None, b, b, v, "keys", True, params, out)
        times = []
        for _ in range(7):
            t = time.process_time()
            for _ in range(n):
                nc.census_form_numba(level, None, b, b, v, "keys", True, params, out)
            times.append((time.process_time() - t) / n)
        res.append(f"{w}x{h} {sorted(times)[3] * 1e9 / (w * h):.2f} ns/px {float(out.sum()):.6e}")
    print(" | ".join(res))


if __name__ == "__main__":
    main()
