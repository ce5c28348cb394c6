"""Prototype (not in the package): the linearisation's gathers from the source planes interleaved as (H, W, 4)
(I1, dI1/dx, dI1/dy, 0), so that each tap is one 4-lane load (SLP), against main's linearise_kernel on the
same data; one thread; prints medians and the max |difference| of a and c; plus the interleaving copy's cost."""
import time

import numpy as np
from numba import njit

from flow_node import process

process.passive_thread_waits()
from flow_node.core import numba_backend as nb  # noqa: E402
from flow_node.core import numba_warp as nw  # noqa: E402

_HALF = np.float32(0.5)


@njit(fastmath=True, error_model="numpy")
def lin4(i0, src4, g0, flow, kernel, a, c, scratch, base):  # noqa: ANN001, ANN201
    h, w = i0.shape
    zero = np.float32(0.0)
    for i in range(h):
        nw.row_taps(flow, i, h, w, kernel, scratch, base)
        for j in range(w):
            if scratch[8, j] == zero:
                a[0, i, j] = 0
                a[1, i, j] = 0
                c[i, j] = 0
                continue
            wx, wy, cols, rows = nw.row_block(scratch, base, j, h, w)
            s0 = s1 = s2 = s3 = zero
            for r in range(4):
                rr = np.uint64(rows[r])
                t0 = t1 = t2 = t3 = zero
                for k in range(4):
                    cc = np.uint64(cols[k])
                    t0 += wx[k] * src4[rr, cc, 0]
                    t1 += wx[k] * src4[rr, cc, 1]
                    t2 += wx[k] * src4[rr, cc, 2]
                    t3 += wx[k] * src4[rr, cc, 3]
                s0 += wy[r] * t0
                s1 += wy[r] * t1
                s2 += wy[r] * t2
                s3 += wy[r] * t3
            a0 = _HALF * (g0[0, i, j] + s1)
            a1 = _HALF * (g0[1, i, j] + s2)
            a[0, i, j] = a0
            a[1, i, j] = a1
            c[i, j] = s0 - i0[i, j] - a0 * flow[0, i, j] - a1 * flow[1, i, j]


SIZES = ((120, 160), (240, 320), (480, 640)) if __name__ == "__main__" else ((24, 32),)
for h, w in SIZES:
    rng = np.random.default_rng(0)
    i0 = rng.random((h, w), np.float32)
    src = rng.random((3, h, w), np.float32)
    g0 = rng.random((2, h, w), np.float32)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    flow = np.stack([3 * np.sin(xx / 17) + 1.5, 2 * np.cos(yy / 13)]).astype(np.float32)
    a, c = np.empty((2, h, w), np.float32), np.empty((h, w), np.float32)
    a4, c4 = np.empty_like(a), np.empty_like(c)
    rows, base = nb.row_scratch(w)
    src4 = np.zeros((h, w, 4), np.float32)
    tm, tp, tc = [], [], []
    for _ in range(41):
        t = time.perf_counter()
        nw.linearise_kernel(i0, src, g0, flow, 1, True, a, c, rows, base, False)
        tm.append(time.perf_counter() - t)
        t = time.perf_counter()
        src4[:, :, :3] = src.transpose(1, 2, 0)
        tc.append(time.perf_counter() - t)
        t = time.perf_counter()
        lin4(i0, src4, g0, flow, 1, a4, c4, rows[0], base[0])
        tp.append(time.perf_counter() - t)
    tm, tp, tc = (1e3 * np.median(x[1:]) for x in (tm, tp, tc))
    print(f"{w}x{h}: main {tm:.3f} ms, interleaved {tp:.3f} ms ({tp / tm:.2f}x), copy {tc:.3f} ms; "
          f"max |da| {np.abs(a - a4).max():.2e}, |dc| {np.abs(c - c4).max():.2e}")
