"""Throwaway (task censlarge): one warp's census kernel against the grey linearisation on a fine_320 level, and the
census kernel's three steps timed apart (each over all rows of the level with the kernel's own ring buffers):
the warp of frame 1's rows (sample_row), the signatures' P and D rows (_pair_rows), the form (_form_rows).
``widths``: the three steps' time per row on random 60-row levels 16-640 px wide (the rows' fixed cost).
PYTHONPATH=. python bench/results/census_cost/censlarge/micro.py [widths]"""
from __future__ import annotations

import sys
import time

import numpy as np
from numba import njit

from bench.suite import synthetic
from flow_node.core import numba_census as nc
from flow_node.core.census import CENSUS
from flow_node.core.numba_backend import WARPER, linearise_numba, row_scratch
from flow_node.core.numba_warp import sample_row
from flow_node.core.warping import KERNEL_CODES
from flow_node.core.workspace import scratch


@njit(cache=False)
def _warp_all(coefs, frames, flow, kernel, warped, keep, taps, base, reps):  # noqa: ANN001, ANN202
    h = frames.shape[1]
    m = warped.shape[1]
    for _ in range(reps):
        for r in range(h):
            s = r % m
            sample_row(coefs, frames, flow, r, kernel, np.float32(1.0), warped, s, keep[s], taps, base)


@njit(cache=False)
def _pair_all(f0, warped, dy, dx, gain, eps, pair, diff, temp, ss, reps):  # noqa: ANN001, ANN202
    h = f0.shape[1]
    for _ in range(reps):
        for r in range(h):
            nc._pair_rows(f0, r, warped, 0, 1, 2, r % 3, dy, dx, gain, eps, pair, diff, temp, ss)


@njit(cache=False)
def _form_all(out, pair, diff, keep, flow, d2, robust, reps):  # noqa: ANN001, ANN202
    h = out.shape[1]
    for _ in range(reps):
        for i in range(1, h - 1):
            nc._form_rows(out, i, pair, diff, keep, i % 3, flow, d2, robust)


def best(fn, *args, reps: int = 1, n: int = 7) -> float:  # noqa: ANN001
    """The least CPU time of n runs of ``reps`` calls fn(*args), per call."""
    ts = []
    for _ in range(n):
        t = time.process_time()
        for _ in range(reps):
            fn(*args)
        ts.append(time.process_time() - t)
    return min(ts) / reps


def main() -> None:
    s = next(iter(synthetic.fine("tune", False, (320, 240))))
    import cv2
    for size in ((320, 240), (160, 120), (80, 60)):
        i0 = cv2.resize(s.f0.astype(np.float32), size, interpolation=cv2.INTER_AREA)
        i1 = cv2.resize(s.f1.astype(np.float32), size, interpolation=cv2.INTER_AREA)
        h, w = i0.shape
        flow = np.full((2, h, w), 0.3, np.float32)
        params = CENSUS
        f0, _ = nc.level_signature_numba(i0, params)
        f0 = f0.copy()
        coefs = WARPER.coefficients(i1[None], "bspline").copy()
        frames = i1[None].copy()
        reps = 20
        t_form = best(nc.census_form_numba, f0, None, coefs, frames, flow, "bspline", True, params, reps=reps)
        src = np.stack([i1, *np.gradient(i1)[::-1]]).astype(np.float32)
        src = WARPER.prefilter(src)
        g0 = np.stack(np.gradient(i0)[::-1]).astype(np.float32)
        t_lin = best(linearise_numba, i0, src, g0, flow, "interpolated", "bspline", reps=reps)
        m, q = 3, 8
        warped = np.zeros((1, m, w), np.float32)
        keep = np.zeros((m, w), np.float32)
        pair = np.zeros((q, 3, w + 2), np.float32)
        diff = np.zeros((q, 3, w), np.float32)
        temp = np.zeros((8, 1, w), np.float32)
        ss = np.zeros(w, np.float32)
        taps, base = (x[0] for x in row_scratch(w))
        out = scratch("micro.out", (5, h, w))
        dy, dx = nc._offset_arrays(1)
        k = KERNEL_CODES["bspline"]
        _warp_all(coefs, frames, flow, k, warped, keep, taps, base, 1)
        _pair_all(f0, warped, dy, dx, np.float32(0.1), np.float32(0.01), pair, diff, temp, ss, 1)
        _form_all(out, pair, diff, keep, flow, np.float32(0.0049), True, 1)
        t_w = best(_warp_all, coefs, frames, flow, k, warped, keep, taps, base, reps) / reps
        t_p = best(_pair_all, f0, warped, dy, dx, np.float32(0.1), np.float32(0.01), pair, diff, temp, ss, reps) / reps
        t_f = best(_form_all, out, pair, diff, keep, flow, np.float32(0.0049), True, reps) / reps
        px = h * w
        print(f"{w}x{h}: census_form {1e9 * t_form / px:.1f} ns/px, linearise {1e9 * t_lin / px:.1f} ns/px "
              f"({t_form / t_lin:.2f}x); steps: warp {1e9 * t_w / px:.1f}, P/D {1e9 * t_p / px:.1f}, "
              f"form {1e9 * t_f / px:.1f} ns/px")


def widths() -> None:
    """The three steps per row on random levels of 60 rows and the given widths."""
    rng = np.random.default_rng(0)
    h = 60
    dy, dx = nc._offset_arrays(1)
    for w in (16, 24, 32, 40, 48, 56, 64, 72, 80, 96, 112, 128, 160, 240, 320, 640):
        i0, i1 = rng.random((h, w), dtype=np.float32), rng.random((h, w), dtype=np.float32)
        f0 = nc.level_signature_numba(i0, CENSUS)[0].copy()
        coefs, frames = WARPER.coefficients(i1[None], "bspline").copy(), i1[None].copy()
        flow = np.full((2, h, w), 0.3, np.float32)
        warped, keep = rng.random((1, 3, w), dtype=np.float32), np.ones((3, w), np.float32)
        pair, diff = np.zeros((8, 3, w + 2), np.float32), np.zeros((8, 3, w), np.float32)
        temp, ss, out = np.zeros((8, 1, w), np.float32), np.zeros(w, np.float32), np.zeros((5, h, w), np.float32)
        taps, base = (x[0] for x in row_scratch(w))
        reps = max(1, 20000 // w)
        t_p = best(_pair_all, f0, warped, dy, dx, np.float32(0.1), np.float32(0.01), pair, diff, temp, ss, reps) / reps
        t_f = best(_form_all, out, pair, diff, keep, flow, np.float32(0.0049), True, reps) / reps
        t_w = best(_warp_all, coefs, frames, flow, KERNEL_CODES["bspline"], warped, keep, taps, base, reps) / reps
        print(f"w {w}: ns per row: warp {1e9 * t_w / h:.0f}, P/D {1e9 * t_p / h:.0f}, form {1e9 * t_f / (h - 2):.0f}")


if __name__ == "__main__":
    widths() if sys.argv[1:] == ["widths"] else main()
