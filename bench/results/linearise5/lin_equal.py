"""sha256 of linearise_kernel's (a, c) for both schemes, both kernels, serial/parallel, three sizes, with flows that
leave the image (the tree on PYTHONPATH)."""
import hashlib
import sys

import numpy as np

from flow_node.core import numba_backend as nb
from flow_node.core import numba_warp as nw

hs = hashlib.sha256()
keep = {}
for h, w in ((7, 5), (120, 160), (240, 320)):
    rng = np.random.default_rng(1)
    i0 = rng.random((h, w), np.float32)
    src = rng.random((3, h, w), np.float32)
    g0 = rng.random((2, h, w), np.float32)
    flow = (rng.standard_normal((2, h, w)) * 4).astype(np.float32)
    rows, base = nb.row_scratch(w)
    for kernel in (0, 1):
        for interp in (False, True):
            for par in (False, True):
                a = np.full((2, h, w), np.nan, np.float32)
                c = np.full((h, w), np.nan, np.float32)
                g = g0 if interp else nb.zero_rows(w)["g0"]
                nw.linearise_kernel(i0, src, g, flow, kernel, interp, a, c, rows, base, par)
                hs.update(a.tobytes())
                hs.update(c.tobytes())
                keep[f"{w}_{kernel}_{interp}_{par}_a"], keep[f"{w}_{kernel}_{interp}_{par}_c"] = a, c
print(hs.hexdigest())
if len(sys.argv) > 1:
    np.savez(sys.argv[1], **keep)
