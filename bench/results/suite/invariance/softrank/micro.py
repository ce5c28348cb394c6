"""Task softrank: CPU time of frame 0's level signature and of one warp's census form (numba, one thread, L1) on
random frames at 320x240 and 640x480, saturation off against on (TAU 1.5), interleaved; medians.

    python bench/results/suite/invariance/softrank/micro.py [ROUNDS]
"""

from __future__ import annotations

import sys
import time

import numpy as np

from flow_node.core.census import CensusParams
from flow_node.core.numba_backend import WARPER, thread_count
from flow_node.core.numba_census import census_form_numba, level_signature_numba

SETTINGS = (CensusParams(), CensusParams(saturation=1.5))


def main() -> None:
    rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 15
    rng = np.random.default_rng(0)
    for h, w in ((240, 320), (480, 640)):
        i0 = rng.random((h, w), dtype=np.float32)
        i1 = rng.random((1, h, w), dtype=np.float32)
        coefs = WARPER.coefficients(i1, "bspline")
        v0 = rng.standard_normal((2, h, w)).astype(np.float32)
        res: dict[float, list[tuple[float, float]]] = {}
        with thread_count(1):
            for p in SETTINGS:  # compile / load
                census_form_numba(level_signature_numba(i0, p)[0].copy(), None, coefs, i1, v0, "bspline", True, p)
            for _ in range(rounds):
                for p in SETTINGS:
                    t = time.process_time()
                    f0 = level_signature_numba(i0, p)[0].copy()
                    ts = time.process_time() - t
                    t = time.process_time()
                    for _ in range(5):
                        census_form_numba(f0, None, coefs, i1, v0, "bspline", True, p)
                    res.setdefault(p.saturation, []).append((ts, (time.process_time() - t) / 5))
        for s, v in res.items():
            a = np.median(np.array(v), axis=0) * 1e3
            print(f"{w}x{h} saturation {s}: level signature {a[0]:.3f} ms, form {a[1]:.3f} ms (CPU, median)")


if __name__ == "__main__":
    main()
