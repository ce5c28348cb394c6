"""Time numba_warp.linearise_kernel alone (the tree on PYTHONPATH): interpolated scheme, B-spline taps, a smooth
random flow of a few px; serial and parallel; prints one JSON line {size/mode: median ms over --calls}."""
import json
import sys
import time

import numpy as np

from flow_node import process

process.passive_thread_waits()  # as the executables: libgomp's spin waits cost ~8 ms a region on shared cores
from flow_node.core import numba_backend as nb  # noqa: E402
from flow_node.core import numba_warp as nw  # noqa: E402

calls = int(sys.argv[1]) if len(sys.argv) > 1 else 40
out = {}
for h, w in ((120, 160), (240, 320), (480, 640)):
    rng = np.random.default_rng(0)
    i0 = rng.random((h, w), np.float32)
    src = rng.random((3, h, w), np.float32)
    g0 = rng.random((2, h, w), np.float32)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    flow = np.stack([3 * np.sin(xx / 17) + 1.5, 2 * np.cos(yy / 13)]).astype(np.float32)
    a = np.empty((2, h, w), np.float32)
    c = np.empty((h, w), np.float32)
    rows, base = nb.row_scratch(w)
    for par in (False, True):
        nw.linearise_kernel(i0, src, g0, flow, 1, True, a, c, rows, base, par)
        ts = []
        for _ in range(calls):
            t = time.perf_counter()
            nw.linearise_kernel(i0, src, g0, flow, 1, True, a, c, rows, base, par)
            ts.append(time.perf_counter() - t)
        out[f"{w}x{h}/{'par' if par else 'ser'}"] = 1e3 * float(np.median(ts))
print(json.dumps(out))
