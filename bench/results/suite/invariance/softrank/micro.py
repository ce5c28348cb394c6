"""CPU time of one warp's census form (numba) and a level signature at 320x240 / 640x480, saturation off vs on,
interleaved, one thread."""
import sys
import time
import numpy as np
from flow_node.core.census import CensusParams
from flow_node.core.numba_backend import WARPER, thread_count
from flow_node.core.numba_census import census_form_numba, level_signature_numba

rng = np.random.default_rng(0)
for h, w in ((240, 320), (480, 640)):
    i0 = rng.random((h, w), dtype=np.float32)
    i1 = rng.random((1, h, w), dtype=np.float32)
    coefs = WARPER.coefficients(i1, "bspline")
    v0 = rng.standard_normal((2, h, w)).astype(np.float32)
    res = {}
    with thread_count(1):
        for p in (CensusParams(), CensusParams(saturation=1.5)):
            f0, _ = level_signature_numba(i0, p)
            census_form_numba(f0.copy(), None, coefs, i1, v0, "bspline", True, p)
        for rep in range(int(sys.argv[1]) if len(sys.argv) > 1 else 15):
            for p in (CensusParams(), CensusParams(saturation=1.5)):
                t = time.process_time()
                f0, _ = level_signature_numba(i0, p)
                ts = time.process_time() - t
                f0 = f0.copy()
                t = time.process_time()
                for _ in range(5):
                    census_form_numba(f0, None, coefs, i1, v0, "bspline", True, p)
                tf = (time.process_time() - t) / 5
                res.setdefault(p.saturation, []).append((ts, tf))
    for s, v in res.items():
        a = np.median(np.array(v), axis=0) * 1e3
        print(f"{w}x{h} saturation {s}: level signature {a[0]:.3f} ms, form {a[1]:.3f} ms (CPU, median)")
