"""numba kernels of the 3-D engine (core/volume.py): the primal-dual iteration on volumes and the trilinear
linearisation of one warp (the pyramid's resampling: numba_volume_resample.py).

The same arithmetic as solver.solve_numpy (the oracle) on (Z, Y, X) grids, for all five models (integer
flags as in numba_kernels.py: ``reg`` from REG_CODES, ``data_l1``, ``iso``) and the incompressibility
penalty (``inc``). One dual pass and one primal pass per iteration, each streaming every array once with
grad/div fused into the voxel loop; slices (z) run in parallel (prange). Boundaries as in operators.py:
forward differences are zero across the far border (clamped neighbour index times a 0/1 mask), the
divergence is their exact negative adjoint.

Layout (models.py): v (3, Z, Y, X) with v[0] = x, v[1] = y, v[2] = z; y (3, 3, Z, Y, X) [dir, comp]; w like
y; z (3, 3, 3, Z, Y, X) [dir2, dir, comp]; s (Z, Y, X); a (3, Z, Y, X); c (Z, Y, X); float32 C-contiguous. Loads
stay inside the arrays given whatever the flags (numba_kernels.py, masked loads): what a pixel loop indexes
without its model (w_bar, tv_l2's z, gi0) is a zero row (numba_backend.zero_rows) read at a (slice, row) index
clamped once per row; w and s, read only in row loops that their flag guards, are 1x1x1 dummies.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

from .models import step_sizes
from .numba_backend import PARALLEL_MIN_PIXELS, zero_rows
from .numba_kernels import FASTMATH, REG_CODES
from .solver import CHECK_EVERY, PDState, Problem, SolveParams

# the solver's fastmath flags (numba_kernels.FASTMATH): with fastmath=True (reassoc, arcp) a process that compiled
# these kernels computed other volume flows than every later process reading them from the cache (test_cold_start)
_JIT = dict(fastmath=FASTMATH, cache=True, error_model="numpy", nogil=True)
_ONE = np.float32(1.0)
_ZERO = np.float32(0.0)


@njit(**_JIT)
def dual_slice(k, v_bar, w_bar, y, z, s, sigma, rel1, rel_inc, reg, iso, inc, n2):  # noqa: ANN001, ANN201
    """The dual step on slice k: y <- prox(y + sigma (grad v_bar - w_bar)); z <- proj(z + sigma grad w_bar);
    s <- prox(s + sigma div v_bar). In place; n2: (X,) float32 scratch. Reads v_bar, w_bar on slices k, k + 1.

    Neighbours are clamped (the difference across the far border is then 0); along x the row runs in two
    segments, interior columns (step 1) and the last one (step 0), so the inner loop has no branch."""
    nz, ny, nx = v_bar.shape[1], v_bar.shape[2], v_bar.shape[3]
    l2_scale = _ONE / (_ONE + sigma) if reg == 0 else _ONE
    s_scale = _ONE / (_ONE + sigma / rel_inc) if inc else _ONE
    kn, kw = min(k + 1, nz - 1), min(np.int64(k), w_bar.shape[2] - 1)  # kw, iw: 0 in a zero row
    for i in range(ny):
        i_n, iw = min(i + 1, ny - 1), min(i, w_bar.shape[3] - 1)
        n2[:] = _ZERO
        for c in range(3):
            for seg in range(2):
                j0, j1, rr = (0, nx - 1, 1) if seg == 0 else (nx - 1, nx, 0)
                for j in range(j0, j1):
                    f0 = v_bar[c, k, i, j]
                    gx, gy, gz = v_bar[c, k, i, j + rr] - f0, v_bar[c, k, i_n, j] - f0, v_bar[c, kn, i, j] - f0
                    if reg >= 2:
                        gx -= w_bar[0, c, kw, iw, j]
                        gy -= w_bar[1, c, kw, iw, j]
                        gz -= w_bar[2, c, kw, iw, j]
                    tx = (y[0, c, k, i, j] + sigma * gx) * l2_scale
                    ty = (y[1, c, k, i, j] + sigma * gy) * l2_scale
                    tz = (y[2, c, k, i, j] + sigma * gz) * l2_scale
                    if reg != 0 and not iso:
                        tx, ty, tz = min(max(tx, -_ONE), _ONE), min(max(ty, -_ONE), _ONE), min(max(tz, -_ONE), _ONE)
                    y[0, c, k, i, j] = tx
                    y[1, c, k, i, j] = ty
                    y[2, c, k, i, j] = tz
                    n2[j] += tx * tx + ty * ty + tz * tz
        if reg != 0 and iso:
            _project_rows(y, n2, k, i, _ONE)
        if inc:
            for seg in range(2):
                j0, j1, rr = (0, nx - 1, 1) if seg == 0 else (nx - 1, nx, 0)
                for j in range(j0, j1):
                    dv = (v_bar[0, k, i, j + rr] - v_bar[0, k, i, j] + v_bar[1, k, i_n, j] - v_bar[1, k, i, j]
                          + v_bar[2, kn, i, j] - v_bar[2, k, i, j])
                    s[k, i, j] = (s[k, i, j] + sigma * dv) * s_scale
        if reg == 3:
            _z_row(w_bar, z, n2, k, i, kn, i_n, sigma, rel1, iso)


@njit(**_JIT)
def _x_div(q, p, m, k, i):  # noqa: ANN001, ANN201
    """Pad row (k, i) of p[m] (a (M, Z, Y, X) view) for the x part of the backward divergence: q (X + 1,) =
    (0, p[:-1], 0), so div_x p[j] = q[j + 1] - q[j] with no branch (operators.div's border)."""
    nx = p.shape[3]
    q[0] = _ZERO
    for j in range(nx - 1):
        q[j + 1] = p[m, k, i, j]
    q[nx] = _ZERO


@njit(**_JIT)
def primal_slice(k, v, v_bar, w, w_bar, y, z, s, a, c, tau, tau_d, rel1, data_l1, reg, inc, vt, measure):  # noqa: ANN001, ANN201
    """The primal step on slice k: v <- prox_data(v + tau div(y + diag s)); w <- w + tau (y + div z) (tv_tv)
    or shrunk (tv_l2); the extrapolations v_bar, w_bar. In place; vt: (4, X + 1) float32 scratch. Reads y, z,
    s on slices k - 1, k. Returns sum |v_new - v|^2 over the slice if ``measure``, else 0 (a sum inside the
    pixel loop keeps it from being vectorised without fastmath's "reassoc": the row keeps the change in v_bar,
    sums it when asked and then adds v_new, as numba_kernels' primal pass does)."""
    nz, ny, nx = v.shape[1], v.shape[2], v.shape[3]
    kp, ok, pk = max(k - 1, 0), _ONE if k < nz - 1 else _ZERO, _ONE if k > 0 else _ZERO
    yx = y[0]  # (3, Z, Y, X): the x direction of y, by component
    q = vt[3]
    acc = 0.0
    for i in range(ny):
        ip, oi, pi = max(i - 1, 0), _ONE if i < ny - 1 else _ZERO, _ONE if i > 0 else _ZERO
        for cc in range(3):
            _x_div(q, yx, cc, k, i)
            for j in range(nx):
                dy = (q[j + 1] - q[j] + y[1, cc, k, i, j] * oi - y[1, cc, k, ip, j] * pi
                      + y[2, cc, k, i, j] * ok - y[2, cc, kp, i, j] * pk)
                vt[cc, j] = v[cc, k, i, j] + tau * dy
        if inc:  # s sits on y's diagonal: component cc gets the backward difference of s along cc
            _x_div(q, s.reshape((1,) + s.shape), 0, k, i)
            for j in range(nx):
                vt[0, j] += tau * (q[j + 1] - q[j])
                vt[1, j] += tau * (s[k, i, j] * oi - s[k, ip, j] * pi)
                vt[2, j] += tau * (s[k, i, j] * ok - s[kp, i, j] * pk)
        for j in range(nx):
            a0, a1, a2 = a[0, k, i, j], a[1, k, i, j], a[2, k, i, j]
            r = a0 * vt[0, j] + a1 * vt[1, j] + a2 * vt[2, j] + c[k, i, j]
            aa = a0 * a0 + a1 * a1 + a2 * a2
            step_l1 = min(max(-r / max(aa, np.float32(1e-12)), -tau_d), tau_d)
            step_l2 = -(tau_d * r / (_ONE + tau_d * aa))
            step = step_l1 if data_l1 else step_l2
            n0, n1, n2 = vt[0, j] + step * a0, vt[1, j] + step * a1, vt[2, j] + step * a2
            v_bar[0, k, i, j] = n0 - v[0, k, i, j]  # the change; the extrapolation v_new + change is made below
            v_bar[1, k, i, j] = n1 - v[1, k, i, j]
            v_bar[2, k, i, j] = n2 - v[2, k, i, j]
            v[0, k, i, j] = n0
            v[1, k, i, j] = n1
            v[2, k, i, j] = n2
        if measure:
            for j in range(nx):
                d0, d1, d2 = v_bar[0, k, i, j], v_bar[1, k, i, j], v_bar[2, k, i, j]
                acc += d0 * d0 + d1 * d1 + d2 * d2
        for cc in range(3):
            for j in range(nx):
                v_bar[cc, k, i, j] += v[cc, k, i, j]
        if reg >= 2:
            _w_row(w, w_bar, y, z, k, i, kp, ip, ok, oi, pk, pi, tau, rel1, reg, q)
    return acc


@njit(**_JIT)
def step_fused(v, v_bar, w, w_bar, y, z, s, a, c, tau, sigma, tau_d, rel1, rel_inc, data_l1, reg, iso, inc,  # noqa: ANN001, ANN201
               measure):
    """One whole iteration on one thread as a wavefront: the dual step of slice k, then the primal step of
    slice k - 1, which needs y, z, s only on k - 2 .. k - 1 (already updated) while the dual step of k needs
    v_bar, w_bar on k, k + 1 (not yet). Same result as the two passes, each slice's arrays read while still
    in cache. Returns sum |v_new - v|^2 if ``measure``, else 0."""
    nz, nx = v.shape[1], v.shape[3]
    n2, vt = np.empty(nx, np.float32), np.empty((4, nx + 1), np.float32)
    total = 0.0
    for k in range(nz + 1):
        if k < nz:
            dual_slice(k, v_bar, w_bar, y, z, s, sigma, rel1, rel_inc, reg, iso, inc, n2)
        if k > 0:
            total += primal_slice(k - 1, v, v_bar, w, w_bar, y, z, s, a, c, tau, tau_d, rel1, data_l1, reg, inc, vt,
                                  measure)
    return total


def _make_kernels(parallel: bool):  # noqa: ANN202
    """Compile the dual pass, the primal pass (slices in parallel) and the linearisation, parallel or serial."""

    def dual_pass(v_bar, w_bar, y, z, s, sigma, rel1, rel_inc, reg, iso, inc):  # noqa: ANN001, ANN202
        """:func:`dual_slice` on every slice."""
        for k in prange(v_bar.shape[1]):
            dual_slice(k, v_bar, w_bar, y, z, s, sigma, rel1, rel_inc, reg, iso, inc,
                       np.empty(v_bar.shape[3], np.float32))

    def primal_pass(v, v_bar, w, w_bar, y, z, s, a, c, tau, tau_d, rel1, data_l1, reg, inc, measure):  # noqa: ANN001, ANN202
        """:func:`primal_slice` on every slice; returns sum |v_new - v|^2 if ``measure``, else 0."""
        nz = v.shape[1]
        per_slice = np.zeros(nz)  # a scalar reduction confuses the parfor pass
        for k in prange(nz):
            per_slice[k] = primal_slice(k, v, v_bar, w, w_bar, y, z, s, a, c, tau, tau_d, rel1, data_l1, reg, inc,
                                        np.empty((4, v.shape[3] + 1), np.float32), measure)
        return per_slice.sum()

    def linearise(i0, src, v0, gi0, interpolated, a, c):  # noqa: ANN001, ANN202
        """Trilinear samples of src = [I1, grad I1] (4, Z, Y, X) at x + v0; a = the warped gradient (its mean
        with gi0 when ``interpolated``), c = I1(x + v0) - I0 - a . v0; both 0 where x + v0 leaves the volume."""
        nz, ny, nx = i0.shape
        for k in prange(nz):
            for i in range(ny):
                kg, ig = min(np.int64(k), gi0.shape[1] - 1), min(i, gi0.shape[2] - 1)  # 0 in a zero row
                for j in range(nx):
                    px, py, pz = j + v0[0, k, i, j], i + v0[1, k, i, j], k + v0[2, k, i, j]
                    if not (0.0 <= px <= nx - 1 and 0.0 <= py <= ny - 1 and 0.0 <= pz <= nz - 1):
                        a[0, k, i, j], a[1, k, i, j], a[2, k, i, j], c[k, i, j] = _ZERO, _ZERO, _ZERO, _ZERO
                        continue
                    x0, y0, z0 = min(int(px), nx - 1), min(int(py), ny - 1), min(int(pz), nz - 1)
                    x1, y1, z1 = min(x0 + 1, nx - 1), min(y0 + 1, ny - 1), min(z0 + 1, nz - 1)
                    fx, fy, fz = np.float32(px - x0), np.float32(py - y0), np.float32(pz - z0)
                    s0 = _trilinear(src, 0, x0, y0, z0, x1, y1, z1, fx, fy, fz)
                    s1 = _trilinear(src, 1, x0, y0, z0, x1, y1, z1, fx, fy, fz)
                    s2 = _trilinear(src, 2, x0, y0, z0, x1, y1, z1, fx, fy, fz)
                    s3 = _trilinear(src, 3, x0, y0, z0, x1, y1, z1, fx, fy, fz)
                    if interpolated:
                        s1 = np.float32(0.5) * (gi0[0, kg, ig, j] + s1)
                        s2 = np.float32(0.5) * (gi0[1, kg, ig, j] + s2)
                        s3 = np.float32(0.5) * (gi0[2, kg, ig, j] + s3)
                    a[0, k, i, j], a[1, k, i, j], a[2, k, i, j] = s1, s2, s3
                    c[k, i, j] = (s0 - i0[k, i, j] - s1 * v0[0, k, i, j] - s2 * v0[1, k, i, j]
                                  - s3 * v0[2, k, i, j])

    suffix = "par" if parallel else "ser"
    out = []
    for fn in (dual_pass, primal_pass, linearise):
        fn.__name__ = fn.__qualname__ = f"{fn.__name__}3_{suffix}"
        out.append(njit(parallel=parallel, **_JIT)(fn))
    return tuple(out)


@njit(**_JIT)
def _trilinear(src, ch, x0, y0, z0, x1, y1, z1, fx, fy, fz):  # noqa: ANN001, ANN201
    """Trilinear interpolation of src[ch] between the corners (x0..x1, y0..y1, z0..z1) at fractions f."""
    c00 = src[ch, z0, y0, x0] + fx * (src[ch, z0, y0, x1] - src[ch, z0, y0, x0])
    c01 = src[ch, z0, y1, x0] + fx * (src[ch, z0, y1, x1] - src[ch, z0, y1, x0])
    c10 = src[ch, z1, y0, x0] + fx * (src[ch, z1, y0, x1] - src[ch, z1, y0, x0])
    c11 = src[ch, z1, y1, x0] + fx * (src[ch, z1, y1, x1] - src[ch, z1, y1, x0])
    c0 = c00 + fy * (c01 - c00)
    c1 = c10 + fy * (c11 - c10)
    return c0 + fz * (c1 - c0)


@njit(**_JIT)
def _project_rows(q, n2, k, i, radius):  # noqa: ANN001, ANN201
    """Scale every component q[..., k, i, :] by 1 / max(1, sqrt(n2) / radius) (the isotropic ball); n2 (X,)
    holds |q|^2 per voxel of the row and is overwritten with the scale."""
    for j in range(n2.shape[0]):
        n2[j] = _ONE / max(_ONE, np.float32(math.sqrt(n2[j])) / radius)
    flat = q.reshape((-1,) + q.shape[-3:])
    for m in range(flat.shape[0]):
        for j in range(n2.shape[0]):
            flat[m, k, i, j] *= n2[j]


@njit(**_JIT)
def _z_row(w_bar, z, n2, k, i, kn, i_n, sigma, rel1, iso):  # noqa: ANN001, ANN201
    """z <- projection of z + sigma grad w_bar onto the ball of radius rel1 (27 components), row (k, i)."""
    nx = w_bar.shape[4]
    n2[:] = _ZERO
    for d in range(3):
        for c in range(3):
            for seg in range(2):  # interior columns, then the last (see dual_slice)
                j0, j1, rr = (0, nx - 1, 1) if seg == 0 else (nx - 1, nx, 0)
                for j in range(j0, j1):
                    w0 = w_bar[d, c, k, i, j]
                    tx = z[0, d, c, k, i, j] + sigma * (w_bar[d, c, k, i, j + rr] - w0)
                    ty = z[1, d, c, k, i, j] + sigma * (w_bar[d, c, k, i_n, j] - w0)
                    tz = z[2, d, c, k, i, j] + sigma * (w_bar[d, c, kn, i, j] - w0)
                    if not iso:
                        tx, ty, tz = min(max(tx, -rel1), rel1), min(max(ty, -rel1), rel1), min(max(tz, -rel1), rel1)
                    z[0, d, c, k, i, j] = tx
                    z[1, d, c, k, i, j] = ty
                    z[2, d, c, k, i, j] = tz
                    n2[j] += tx * tx + ty * ty + tz * tz
    if iso:
        _project_rows(z, n2, k, i, rel1)


@njit(**_JIT)
def _w_row(w, w_bar, y, z, k, i, kp, ip, ok, oi, pk, pi, tau, rel1, reg, q):  # noqa: ANN001, ANN201
    """w <- w + tau (y + div z) (tv_tv) or (w + tau y) / (1 + tau rel1) (tv_l2); w_bar = 2 w_new - w. Row
    (k, i); q: (X + 1,) scratch for :func:`_x_div`."""
    nx = w.shape[4]
    shrink = _ONE + tau * rel1
    zk, zi = min(np.int64(k), z.shape[3] - 1), min(i, z.shape[4] - 1)  # z's (slice, row): 0 in tv_l2's zero row
    zkp, zip_ = min(np.int64(kp), zk), min(ip, zi)
    zx = z[0].reshape((9,) + z.shape[3:])  # the x direction of z, (dir, comp) flattened
    for d in range(3):
        for c in range(3):
            if reg == 3:
                _x_div(q, zx, 3 * d + c, k, i)
            for j in range(nx):
                wt = w[d, c, k, i, j] + tau * y[d, c, k, i, j]
                if reg == 3:
                    dz = (q[j + 1] - q[j] + z[1, d, c, zk, zi, j] * oi - z[1, d, c, zk, zip_, j] * pi
                          + z[2, d, c, zk, zi, j] * ok - z[2, d, c, zkp, zi, j] * pk)
                    wt += tau * dz
                else:
                    wt = wt / shrink
                w_bar[d, c, k, i, j] = wt + (wt - w[d, c, k, i, j])
                w[d, c, k, i, j] = wt


dual_pass_par, primal_pass_par, linearise_par = _make_kernels(True)
_, _, linearise_ser = _make_kernels(False)


@njit(**_JIT)
def iterate(v, y, w, z, s, v_bar, w_bar, a, c, tau, sigma, tau_d, rel1, rel_inc,  # noqa: ANN001, ANN201
            data_l1, reg, iso, inc, iterations, tolerance, check_every, parallel):
    """Up to ``iterations`` primal-dual steps (stopping rule of solver.solve_numpy). Returns the count."""
    n = 3.0 * v.shape[1] * v.shape[2] * v.shape[3]
    k = 0
    for k in range(1, iterations + 1):
        measure = tolerance > 0.0 and k % check_every == 0
        if parallel:
            dual_pass_par(v_bar, w_bar, y, z, s, sigma, rel1, rel_inc, reg, iso, inc)
            ss = primal_pass_par(v, v_bar, w, w_bar, y, z, s, a, c, tau, tau_d, rel1, data_l1, reg, inc, measure)
        else:
            ss = step_fused(v, v_bar, w, w_bar, y, z, s, a, c, tau, sigma, tau_d, rel1, rel_inc, data_l1, reg, iso, inc,
                            measure)
        if measure and math.sqrt(ss / n) < tolerance:
            break
    return k


# ------------------------------------------------------------------------------------- the solver's glue
_DUMMY = {n: np.zeros((3,) * n + (1, 1, 1), np.float32) for n in (0, 2)}  # w, s: read in guarded row loops


def _c32(x: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=np.float32)


def _parallel(shape: tuple[int, ...]) -> bool:
    """Parallel kernels for a large grid on more than one thread; else the fused single-thread iteration."""
    return int(np.prod(shape)) >= PARALLEL_MIN_PIXELS and numba.get_num_threads() > 1


def solve_numba(problem: Problem, state: PDState, p: SolveParams) -> int:
    """solver.solve_numpy on a volume with these kernels (same semantics; the state is updated in place,
    made float32 C-contiguous first). Returns the iterations run."""
    spec = p.spec
    inc = p.incompressibility > 0.0
    tau, sigma = step_sizes(spec, 3, inc)
    state.v = _c32(state.v)
    state.y = _c32(state.y)
    if spec.extended:
        state.w = _c32(state.w)
    if spec.regulariser == "tv_tv":
        state.z = _c32(state.z)
    if inc and state.s is None:
        state.s = np.zeros(state.v.shape[1:], np.float32)
    rows = zero_rows(state.v.shape[3], volume=True)
    w = state.w if spec.extended else _DUMMY[2]
    z = state.z if spec.regulariser == "tv_tv" else rows["z"]
    s = _c32(state.s) if inc else _DUMMY[0]
    state.s = s if inc else state.s
    f32 = np.float32
    return iterate(state.v, state.y, w, z, s, state.v.copy(), w.copy() if spec.extended else rows["w_bar"],
                   _c32(problem.a), _c32(problem.c),
                   f32(tau), f32(sigma), f32(tau / p.alpha), f32(p.alpha1 / p.alpha),
                   f32(p.incompressibility / p.alpha), spec.data == "l1", REG_CODES[spec.regulariser],
                   p.tv_norm == "isotropic", inc, p.iterations, p.tolerance, CHECK_EVERY,
                   _parallel(state.v.shape[1:]))


def linearise_numba(i0: np.ndarray, src: np.ndarray, v0: np.ndarray, gi0: np.ndarray | None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """volume.linearise3 with the trilinear kernel: (a (3, Z, Y, X), c (Z, Y, X)) float32."""
    a, c = np.empty((3,) + i0.shape, np.float32), np.empty(i0.shape, np.float32)
    kernel = linearise_par if _parallel(i0.shape) else linearise_ser
    kernel(_c32(i0), _c32(src), _c32(v0), zero_rows(i0.shape[2], volume=True)["gi0"] if gi0 is None else _c32(gi0),
           gi0 is not None, a, c)
    return a, c
