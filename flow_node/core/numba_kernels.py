"""numba kernels of the primal-dual iteration: one fused dual pass and one fused primal pass per iteration.

The same arithmetic as solver.solve_numpy (the oracle), in the same order, for every model: the model is
a few integer flags (see :data:`REG_CODES`); the dual pass is compiled per regulariser and the primal pass
per data term (:func:`_make_passes`), one iteration kernel per data term (:data:`ITERATE_NAMES`). Each
pass streams every array once (grad/div and the prox operators are fused into the pixel loop); the
iteration loop runs inside compiled code, so there is no per-iteration Python call and no allocation.
Per-pixel helpers take and return scalars only (no arrays: LLVM inlines them and no reference counting
happens in the pixel loop); the extra variables of the extended models (w, z) are
updated in their own row loops, so the model flags branch outside the loops that matter.

Array layout (models.py): v (2, H, W), y (2, 2, H, W) [dir, comp], w (2, 2, H, W), z (2, 2, 2, H, W)
[dir2, dir, comp], a (2, H, W), c (H, W), b (2, H, W); all float32 C-contiguous. Models without w/z
pass 1x1 dummies of the same rank where only a row function reads them (w, z, m, sp), zero rows where a
pixel loop indexes them (w_bar (2, 2, 1, W); without mass p (1, W), tv (2, 1, W), qpad (2, 2, 1, W + 2));
without a Bregman term b is a (2, 1, W) zero row; without an edge weight
g (H, W) (the radius of y's ball, edges.py) a (1, W) row of ones.

Every load stays inside the array it indexes, whatever the flags (``mass``, ``quad``, ``ext``): LLVM turns the
flag branches of a pixel loop into AVX-512 masked loads, and a masked-off lane whose address lies on a page
that is not mapped or not yet touched costs a microcode assist (fault suppression) on every vector step. A
data term without ``quad`` has 2 planes, not 5, and the extra variables of a model without them are zero
rows (1 row, the level's width) -- so plane and row indices are clamped once per row (like ``b``'s), never
per pixel. Unclamped, the quadratic term's planes 2-4 of a 2-plane ``a`` lay past its end, in a fresh
process on the heap's untouched top: its first flow ran the primal pass ~8x slower (issue 29, docs/engine.md
"Compiled kernels").

Boundaries: grad is the forward difference with a zero last column/row, div the backward difference that
is its exact negative adjoint (operators.py): rows use clamped neighbour indices times a 0/1 mask, columns
segments -- first column, interior, last column -- whose neighbour offsets and 0/1 weights are written
inline per segment: LLVM unrolls the segment loop and constant-folds them, so the interior loop has unit
stride and no branches and vectorises (a helper function returning them, or a clamped index, does not).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

REG_CODES = {"l2": 0, "tv": 1, "tv_l2": 2, "tv_tv": 3}  # regulariser -> integer flag of the kernels

# The solver's fastmath: finite values (nnan, ninf), signed zeros do not matter (nsz), fused multiply-add
# (contract) -- but no "reassoc", "afn" or "arcp", which let a vectorised loop body compute other values than
# the scalar iterations of the same loop; which elements take which path can depend on the arrays' addresses,
# and the iterations amplify the last-bit differences: with them a process's first solve of a pair came out
# 3e-5-8e-4 px away from its later solves of the same pair. With these flags every solve of the same input
# is bit for bit the same (test_cold_start). The census and 3-D kernels use these flags too (numba_census,
# numba_volume: compiled and cached otherwise differed); the warp and
# confidence kernels keep fastmath=True.
FASTMATH = {"nnan", "ninf", "nsz", "contract"}
# error_model numpy: no zero-check branch per division; nogil: a kernel releases the GIL, so another
# thread of the process (a Dask worker's event loop, the node's executor) is not held up for its duration
_JIT = dict(fastmath=FASTMATH, cache=True, error_model="numpy", nogil=True)
_ONE = np.float32(1.0)
_ZERO = np.float32(0.0)


# ------------------------------------------------------------------------------- scalar pixel helpers
@njit(**_JIT)
def prox_dual4(t0, t1, t2, t3, reg, iso, r):  # noqa: ANN001, ANN201
    """prox of sigma F* for the four components of y at one pixel (t = y + sigma K x).

    reg 0 (quadratic regulariser): t / (1 + sigma / r) is done by the caller's ``l2_scale``; here: TV ball of
    radius r (1, or the pixel's edge weight g: models.project_dual_tv), Euclidean over the four components (iso)
    or componentwise clip. With r = 1 the same values bit for bit as the unit ball (x / 1 is exact)."""
    if reg == 0:
        return t0, t1, t2, t3
    if iso:
        m = max(_ONE, math.sqrt(t0 * t0 + t1 * t1 + t2 * t2 + t3 * t3) / r)
        return t0 / m, t1 / m, t2 / m, t3 / m
    return (min(max(t0, -r), r), min(max(t1, -r), r),
            min(max(t2, -r), r), min(max(t3, -r), r))


@njit(**_JIT)
def prox_data_metric(vt0, vt1, a0, a1, c, t0, t1, lam, data_l1, soft):  # noqa: ANN001, ANN201
    """prox of lam * D at one pixel in the metric of the per-component steps (t0, t1) (models.prox_data_metric),
    D = |rho| (l1) or rho^2 / 2 (l2); rho = a . v + c: v_new = vt + s T a. -> v_new.

    l1: the paper's three cases (step +lam T a, -lam T a, or onto rho = 0) are exactly the clip of the
    projection's s = -rho / (a . T a) to [-lam, lam]; written as a clip (and both data terms computed and
    selected) the pixel loop has no branches and vectorises. ``soft`` = 2 gamma / lam (t = 1) turns the l1 term
    into the joint model's J_gamma (models.prox_data_joint): the same clip of -rho / (|a|^2 + soft); 0 = l1."""
    r = a0 * vt0 + a1 * vt1 + c
    q = t0 * a0 * a0 + t1 * a1 * a1
    step_l1 = min(max(-r / max(q + soft, np.float32(1e-12)), -lam), lam)
    step_l2 = -(lam * r / (_ONE + lam * q))
    step = step_l1 if data_l1 else step_l2
    return vt0 + step * t0 * a0, vt1 + step * t1 * a1


@njit(**_JIT)
def prox_data(vt0, vt1, a0, a1, c, tau_d, data_l1, soft):  # noqa: ANN001, ANN201
    """prox of tau_d * D at one pixel (:func:`prox_data_metric` with unit metric; the constant 1s fold away)."""
    return prox_data_metric(vt0, vt1, a0, a1, c, _ONE, _ONE, tau_d, data_l1, soft)


@njit(**_JIT)
def prox_quadratic(vt0, vt1, t11, t12, t22, g0, g1, tau_d):  # noqa: ANN001, ANN201
    """prox of tau_d * (v^T T v / 2 + g . v) at one pixel (models.prox_data_quadratic): the 2 x 2 solve
    (I + tau_d T) v = vt - tau_d g. -> v_new."""
    m00 = _ONE + tau_d * t11
    m01 = tau_d * t12
    m11 = _ONE + tau_d * t22
    r0 = vt0 - tau_d * g0
    r1 = vt1 - tau_d * g1
    inv = _ONE / (m00 * m11 - m01 * m01)
    return (m11 * r0 - m01 * r1) * inv, (m00 * r1 - m01 * r0) * inv


@njit(**_JIT)
def _mass_px(i, j, jl, jr, wx, iu, idn, wy, v_bar, a, m, c, p, qpad, sp, lam, data_l1, rl):  # noqa: ANN001, ANN201
    """The data dual at pixel (i, j): p <- prox_{sigma_p D*}(p + sigma_p (A v_bar + c)) (models.prox_dual_data),
    relaxed by ``rl`` = rho - 1 (solver.relax: p~ + rl (p~ - p); 0 = plain), then qpad[k, l, i + 1, j + 1] =
    M[k, l] p, zero where the central difference along l is (border): what the primal pass's A* reads.
    jl/jr, iu/idn: clamped neighbours; wx, wy: 1 inside, 0 on the border."""
    hx = np.float32(0.5) * wx
    hy = np.float32(0.5) * wy
    r = (a[0, i, j] * v_bar[0, i, j] + a[1, i, j] * v_bar[1, i, j] + c[i, j]
         + hx * (m[0, 0, i, j] * (v_bar[0, i, jr] - v_bar[0, i, jl])
                 + m[1, 0, i, j] * (v_bar[1, i, jr] - v_bar[1, i, jl]))
         + hy * (m[0, 1, i, j] * (v_bar[0, idn, j] - v_bar[0, iu, j])
                 + m[1, 1, i, j] * (v_bar[1, idn, j] - v_bar[1, iu, j])))
    p0 = p[i, j]
    t = p0 + sp[i, j] * r
    pn = min(max(t, -lam), lam) if data_l1 else t / (_ONE + sp[i, j] / lam)
    pn = pn + rl * (pn - p0)
    p[i, j] = pn
    for k in range(2):
        qpad[k, 0, i + 1, j + 1] = m[k, 0, i, j] * pn * wx
        qpad[k, 1, i + 1, j + 1] = m[k, 1, i, j] * pn * wy


@njit(**_JIT)
def p_row(i, v_bar, a, m, c, p, qpad, sp, lam, data_l1, rl):  # noqa: ANN001, ANN201
    """The mass-preservation data dual, row i (:func:`_mass_px`, relaxed by ``rl``): the two border columns, then
    the interior (no index tests in its loop)."""
    h, wd = v_bar.shape[1], v_bar.shape[2]
    wy = _ONE if (i >= 1 and i <= h - 2) else _ZERO
    iu, idn = max(i - 1, 0), min(i + 1, h - 1)
    _mass_px(i, 0, 0, 0, _ZERO, iu, idn, wy, v_bar, a, m, c, p, qpad, sp, lam, data_l1, rl)
    if wd > 1:
        _mass_px(i, wd - 1, wd - 1, wd - 1, _ZERO, iu, idn, wy, v_bar, a, m, c, p, qpad, sp, lam, data_l1, rl)
    for j in range(1, wd - 1):
        _mass_px(i, j, j - 1, j + 1, _ONE, iu, idn, wy, v_bar, a, m, c, p, qpad, sp, lam, data_l1, rl)


# ------------------------------------------------------------------------------------ row updates
@njit(**_JIT)
def z_row(i, ir, rm, w_bar, z, sigma, rel1, iso, rl):  # noqa: ANN001, ANN201
    """z <- projection of z + sigma grad w_bar onto the ball of radius rel1 (8 components per pixel,
    Euclidean if iso else clip), relaxed by ``rl`` = rho - 1 (solver.relax; 0 = plain), row i."""
    wd = z.shape[4]
    for seg in range(2):
        j0, j1, rr = (0, wd - 1, 1) if seg == 0 else (wd - 1, wd, 0)
        for j in range(j0, j1):
            _z_px(i, j, j + rr, ir, rm, w_bar, z, sigma, rel1, iso, rl)


@njit(**_JIT)
def _z_px(i, j, jr, ir, rm, w_bar, z, sigma, rel1, iso, rl):  # noqa: ANN001, ANN201
    """z update at one pixel (see :func:`z_row`): the ball's scale from the 8 components first (isotropic), then
    each component projected and relaxed against its old value."""
    n2 = _ZERO
    if iso:
        for d in range(2):
            for cc in range(2):
                wc = w_bar[d, cc, i, j]
                qx = z[0, d, cc, i, j] + sigma * (w_bar[d, cc, i, jr] - wc)
                qy = z[1, d, cc, i, j] + sigma * ((w_bar[d, cc, ir, j] - wc) * rm)
                n2 += qx * qx + qy * qy
    m = max(_ONE, np.float32(math.sqrt(n2)) / rel1)
    for d in range(2):
        for cc in range(2):
            wc = w_bar[d, cc, i, j]
            zx, zy = z[0, d, cc, i, j], z[1, d, cc, i, j]
            qx = zx + sigma * (w_bar[d, cc, i, jr] - wc)
            qy = zy + sigma * ((w_bar[d, cc, ir, j] - wc) * rm)
            if iso:
                qx, qy = qx / m, qy / m
            else:
                qx = min(max(qx, -rel1), rel1)
                qy = min(max(qy, -rel1), rel1)
            z[0, d, cc, i, j] = qx + rl * (qx - zx)
            z[1, d, cc, i, j] = qy + rl * (qy - zy)


@njit(**_JIT)
def w_row(i, iu, ru, rd, w, w_bar, y, z, tau, rel1, reg, rl):  # noqa: ANN001, ANN201
    """w~ = w + tau (y + div z) (tv_tv) or (w + tau y) / (1 + tau rel1) (tv_l2); w_bar = 2 w~ - w and
    w <- w~ + rl (w~ - w) (rl = rho - 1, solver.relax; 0 = plain). Row i."""
    wd = w.shape[3]
    shrink = _ONE + tau * rel1
    for d in range(2):
        for cc in range(2):
            for seg in range(3):  # first column, interior, last column (see module docstring)
                j0 = 0 if seg == 0 else (1 if seg == 1 else max(wd - 1, 1))
                j1 = min(wd, 1) if seg == 0 else (max(wd - 1, 1) if seg == 1 else wd)
                lo = 1 if seg == 0 else 0  # left neighbour j - 1 + lo
                cl = _ZERO if seg == 0 else _ONE
                cr = _ZERO if (seg == 2 or wd == 1) else _ONE
                for j in range(j0, j1):
                    wt = w[d, cc, i, j] + tau * y[d, cc, i, j]
                    if reg == 3:
                        dz = (z[0, d, cc, i, j] * cr - z[0, d, cc, i, j - 1 + lo] * cl
                              + z[1, d, cc, i, j] * rd - z[1, d, cc, iu, j] * ru)
                        wt += tau * dz
                    else:
                        wt = wt / shrink
                    dw = wt - w[d, cc, i, j]
                    w_bar[d, cc, i, j] = wt + dw
                    w[d, cc, i, j] = wt + rl * dw


# The data terms the primal pass is compiled for (compile-time constants of its pixel loop, :func:`_make_passes`):
# rho = a . v + c pointwise; a quadratic form (census); mass preservation (dualised); mass with the brightness term
PLAIN, QUAD, MASS, BC = 0, 1, 2, 3
DATA_NAMES = ("plain", "quad", "mass", "bc")


def data_code(quad: bool, mass: bool, bc: bool) -> int:
    """The data-term variant (:data:`PLAIN` ... :data:`BC`) of a problem with these flags."""
    return BC if bc else MASS if mass else QUAD if quad else PLAIN


def _make_passes(parallel: bool, data: int | None = None, regulariser: int = 0):  # noqa: ANN202
    """Compile one pass with prange parallel over rows, or serial (prange runs as range): with ``data`` None the
    dual pass for the ``regulariser`` (a :data:`REG_CODES` value; its data-term work, the mass dual, is a per-row
    branch); else the primal pass for that data term (:data:`PLAIN` ... :data:`BC`). Either is a compile-time
    constant, so the pixel loop carries that regulariser's or data term's code only: with them as run-time
    flags LLVM if-converts the loop and every pixel computes every variant's step, with masked loads of the
    absent arrays (10 iterations of the plain term with TV at 160x120: 463 -> 362 us, bit for bit the same
    values; earlier the brightness term in the loop kept it from being vectorised, +35 % per stream frame at
    320x240).

    Distinct function names keep the on-disk cache entries of the variants apart."""
    bc = data == BC

    def dual_pass(v_bar, w_bar, y, z, sigma, rel1, reg, iso, mass, a, m, c, p, qpad, sp, lam, data_l1, g, rl):  # noqa: ANN001, ANN202
        """One dual step over the whole image, in place on y (and z, and with ``mass`` the data dual p). ``g``: the
        edge weight (H, W) of the first regulariser term (the radius of y's ball, :func:`prox_dual4`), or without
        one a (1, W) row of ones (row index clamped, like ``b``'s). ``rl`` = rho - 1: each new dual is relaxed
        against its old value, t + rl (t - old) (solver.relax; 0 = plain, the same values bit for bit)."""
        h, wd = v_bar.shape[1], v_bar.shape[2]
        reg = regulariser  # the argument agrees with this variant's constant
        ext = reg >= 2
        for i in prange(h):
            ig = min(np.int64(i), g.shape[0] - 1)
            ir = min(i + 1, h - 1)
            rm = _ONE if i < h - 1 else _ZERO
            iw = min(np.int64(i), w_bar.shape[2] - 1)  # w_bar is a (2, 2, 1, W) zero row without w
            for seg in range(2):  # interior columns (right neighbour j + 1), then the last column (none)
                j0, j1, rr = (0, wd - 1, 1) if seg == 0 else (wd - 1, wd, 0)
                for j in range(j0, j1):
                    jr = j + rr
                    g00 = v_bar[0, i, jr] - v_bar[0, i, j]
                    g01 = v_bar[1, i, jr] - v_bar[1, i, j]
                    g10 = (v_bar[0, ir, j] - v_bar[0, i, j]) * rm
                    g11 = (v_bar[1, ir, j] - v_bar[1, i, j]) * rm
                    if ext:
                        g00 -= w_bar[0, 0, iw, j]
                        g01 -= w_bar[0, 1, iw, j]
                        g10 -= w_bar[1, 0, iw, j]
                        g11 -= w_bar[1, 1, iw, j]
                    r = g[ig, j]
                    l2_scale = _ONE / (_ONE + sigma / r) if reg == 0 else _ONE
                    y0, y1, y2, y3 = y[0, 0, i, j], y[0, 1, i, j], y[1, 0, i, j], y[1, 1, i, j]
                    t0, t1, t2, t3 = prox_dual4(
                        (y0 + sigma * g00) * l2_scale, (y1 + sigma * g01) * l2_scale,
                        (y2 + sigma * g10) * l2_scale, (y3 + sigma * g11) * l2_scale,
                        reg, iso, r)
                    y[0, 0, i, j] = t0 + rl * (t0 - y0)
                    y[0, 1, i, j] = t1 + rl * (t1 - y1)
                    y[1, 0, i, j] = t2 + rl * (t2 - y2)
                    y[1, 1, i, j] = t3 + rl * (t3 - y3)
            if reg == 3:
                z_row(i, ir, rm, w_bar, z, sigma, rel1, iso, rl)
            if mass:
                p_row(i, v_bar, a, m, c, p, qpad, sp, lam, data_l1, rl)

    def primal_pass(v, v_bar, w, w_bar, y, z, a, c, b, xbuf, tau, tau_d, rel1, data_l1, reg, has_b, quad,  # noqa: ANN001, ANN202
                    soft, mass, p, qpad, tv, measure, ab, cb, lam, rl):
        """One primal step over the whole image, in place on v, v_bar (and w, w_bar); returns
        sum |v_new - v|^2 if ``measure``, else 0 (a sum inside the row loop would keep it from being vectorised:
        fastmath without "reassoc" may not reorder it; so the row keeps the change in v_bar, sums it when
        asked and then adds v_new). xbuf: (threads, 2, W + 1) scratch for the x-part of div y (see below). ``quad``:
        ``a`` is a quadratic data term (5, H, W) (:func:`prox_quadratic`; ``c`` unused), else rho = a . v + c.
        ``mass``: the data term is dualised: v <- v + tv (div y + b - A* p), per-pixel tv, A* p = a p + the
        central differences' adjoint of ``qpad`` = M p (zero-padded by one pixel, see :func:`_mass_px`); ``bc``
        (with ``mass``): then the prox of lam D on the brightness term ab . v + cb in the metric tv
        (:func:`prox_data_metric`). ``rl`` = rho - 1: v (and w) <- x~ + rl (x~ - x), v_bar = 2 x~ - x with the
        unrelaxed x~ (solver.relax; 0 = plain, the same values bit for bit)."""
        h, wd = v.shape[1], v.shape[2]
        # the data term is a constant of this variant (the arguments ``quad`` and ``mass`` agree with it), so
        # the pixel loop keeps its path alone
        mass = data == MASS or data == BC
        quad = data == QUAD
        total = 0.0
        last = a.shape[0] - 1  # the quadratic term's planes 2-4 (a is (2, H, W) without it: read plane 1 instead)
        k2, k3, k4 = min(2, last), min(3, last), min(4, last)
        for i in prange(h):
            iu = max(i - 1, 0)
            ru = _ONE if i > 0 else _ZERO
            rd = _ONE if i < h - 1 else _ZERO
            ib = min(np.int64(i), b.shape[1] - 1)  # b is a (2, 1, W) zero row when there is no Bregman term
            # without mass, p (1, W), tv (2, 1, W) and qpad (2, 2, 1, W + 2) are zero rows: clamped row indices
            ip, it = min(np.int64(i), p.shape[0] - 1), min(np.int64(i), tv.shape[1] - 1)
            qlast = qpad.shape[2] - 1
            q0, q1, q2 = min(np.int64(i), qlast), min(np.int64(i) + 1, qlast), min(np.int64(i) + 2, qlast)
            # x-part of div y: px[j] (j < W-1) - px[j-1] (j > 0) = q[j + 1] - q[j] with q = (0, px[:-1], 0)
            q = xbuf[numba.get_thread_id()]
            q[0, 0] = _ZERO
            q[1, 0] = _ZERO
            for j in range(wd - 1):
                q[0, j + 1] = y[0, 0, i, j]
                q[1, j + 1] = y[0, 1, i, j]
            q[0, wd] = _ZERO
            q[1, wd] = _ZERO
            acc = 0.0
            for j in range(wd):
                div0 = q[0, j + 1] - q[0, j] + y[1, 0, i, j] * rd - y[1, 0, iu, j] * ru
                div1 = q[1, j + 1] - q[1, j] + y[1, 1, i, j] * rd - y[1, 1, iu, j] * ru
                v0, v1 = v[0, i, j], v[1, i, j]
                vt0, vt1 = v0 + tau * (div0 + b[0, ib, j]), v1 + tau * (div1 + b[1, ib, j])
                if mass:
                    s0 = a[0, i, j] * p[ip, j] + np.float32(0.5) * (
                        qpad[0, 0, q1, j] - qpad[0, 0, q1, j + 2]
                        + qpad[0, 1, q0, j + 1] - qpad[0, 1, q2, j + 1])
                    s1 = a[1, i, j] * p[ip, j] + np.float32(0.5) * (
                        qpad[1, 0, q1, j] - qpad[1, 0, q1, j + 2]
                        + qpad[1, 1, q0, j + 1] - qpad[1, 1, q2, j + 1])
                    n0 = v0 + tv[0, it, j] * (div0 + b[0, ib, j] - s0)
                    n1 = v1 + tv[1, it, j] * (div1 + b[1, ib, j] - s1)
                    if bc:
                        n0, n1 = prox_data_metric(n0, n1, ab[0, i, j], ab[1, i, j], cb[i, j], tv[0, it, j],
                                                  tv[1, it, j], lam, data_l1, _ZERO)
                elif quad:
                    n0, n1 = prox_quadratic(vt0, vt1, a[0, i, j], a[1, i, j], a[k2, i, j], a[k3, i, j], a[k4, i, j],
                                            tau_d)
                else:
                    n0, n1 = prox_data(vt0, vt1, a[0, i, j], a[1, i, j], c[i, j], tau_d, data_l1, soft)
                e0, e1 = n0 - v0, n1 - v1  # the change; measured, the extrapolation v_new + change is made below
                v_bar[0, i, j] = e0 if measure else e0 + n0
                v_bar[1, i, j] = e1 if measure else e1 + n1
                v[0, i, j] = n0 + rl * e0
                v[1, i, j] = n1 + rl * e1
            if measure:  # the row's sum of squared changes (not inside the loop above: see the docstring)
                for j in range(wd):
                    acc += v_bar[0, i, j] * v_bar[0, i, j] + v_bar[1, i, j] * v_bar[1, i, j]
                for j in range(wd):  # v - rl e = n (rl = 0: exactly)
                    v_bar[0, i, j] += v[0, i, j] - rl * v_bar[0, i, j]
                    v_bar[1, i, j] += v[1, i, j] - rl * v_bar[1, i, j]
            if reg >= 2:
                w_row(i, iu, ru, rd, w, w_bar, y, z, tau, rel1, reg, rl)
            total += acc
        return total

    fn = dual_pass if data is None else primal_pass
    variant = REG_NAMES[regulariser] if data is None else DATA_NAMES[data]
    fn.__name__ = fn.__qualname__ = f"{fn.__name__}_{'par' if parallel else 'ser'}_{variant}"
    return njit(parallel=parallel, **_JIT)(fn)


REG_NAMES = tuple(REG_CODES)  # by code
dual_pass_par_l2, dual_pass_ser_l2 = _make_passes(True, None, 0), _make_passes(False, None, 0)
dual_pass_par_tv, dual_pass_ser_tv = _make_passes(True, None, 1), _make_passes(False, None, 1)
dual_pass_par_tv_l2, dual_pass_ser_tv_l2 = _make_passes(True, None, 2), _make_passes(False, None, 2)
dual_pass_par_tv_tv, dual_pass_ser_tv_tv = _make_passes(True, None, 3), _make_passes(False, None, 3)
primal_pass_par_plain, primal_pass_ser_plain = _make_passes(True, PLAIN), _make_passes(False, PLAIN)
primal_pass_par_quad, primal_pass_ser_quad = _make_passes(True, QUAD), _make_passes(False, QUAD)
primal_pass_par_mass, primal_pass_ser_mass = _make_passes(True, MASS), _make_passes(False, MASS)
primal_pass_par_bc, primal_pass_ser_bc = _make_passes(True, BC), _make_passes(False, BC)


def _make_iterate(data: int):  # noqa: ANN202
    """The iteration driver over the primal passes of one data term (``data``, :data:`PLAIN` ... :data:`BC`):
    :data:`iterate` (rho = a . v + c), :data:`iterate_quad`, :data:`iterate_mass` and :data:`iterate_bc` (mass
    with the brightness term ``ab``, ``cb``); one source, four kernels (:data:`ITERATE_NAMES` by code). ``data`` is a
    constant of the closure: numba prunes the other branches before typing, so each kernel links only its own
    primal passes (and the kernels reference the passes as module globals, which numba's cache can key)."""

    def iterate(v, y, w, z, v_bar, w_bar, a, c, b, xbuf, tau, sigma, tau_d, rel1,  # noqa: ANN001, ANN202
                data_l1, soft, reg, iso, has_b, iterations, tolerance, check_every, parallel, quad,
                mass, m, p, qpad, sp, tv, lam, ab, cb, g, rl):
        """Up to ``iterations`` primal-dual steps; stops when, every ``check_every`` steps, the RMS change of v
        per iteration is below ``tolerance`` (if > 0). ``parallel`` selects the prange kernels (else serial,
        cheaper on small levels); ``quad``: ``a`` is a quadratic data term (see primal_pass); ``soft``: the joint
        model's data term (:func:`prox_data`; 0 = the model's own); ``mass``: mass
        preservation, M = ``m`` (2, 2, H, W), its dual ``p`` (H, W), the scratch ``qpad`` (2, 2, H + 2, W + 2) of
        M p (zero ring), the steps ``sp`` (H, W) and ``tv`` (2, H, W) (models.mass_steps) and the data weight
        ``lam`` (else dummies; zero rows for p, qpad and tv: numba_backend.zero_rows); in ``iterate_bc``, with
        mass, the brightness term ``ab`` (2, H, W), ``cb`` (H, W) beside it (models.prox_data_metric; else
        dummies); ``g`` the edge weight (H, W) of the first regulariser term, or a (1, W) row of ones
        (:func:`prox_dual4`); ``rl`` = rho - 1 of the over-relaxed iteration (float32; 0 = plain, solver.relax).
        Returns the number of iterations run."""
        n = 2.0 * v.shape[1] * v.shape[2]
        k = 0
        head = (v, v_bar, w, w_bar, y, z, a, c, b, xbuf, tau, tau_d, rel1, data_l1, reg, has_b, quad, soft, mass, p,
                qpad, tv)
        dual = (v_bar, w_bar, y, z, sigma, rel1, reg, iso, mass, a, m, c, p, qpad, sp, lam, data_l1, g, rl)
        for k in range(1, iterations + 1):
            measure = tolerance > 0.0 and k % check_every == 0
            tail = (measure, ab, cb, lam, rl)
            # the regulariser's dual pass and the data term's primal pass (branches per pass, not per pixel)
            if parallel:
                _ = (dual_pass_par_l2(*dual) if reg == 0 else dual_pass_par_tv(*dual) if reg == 1
                     else dual_pass_par_tv_l2(*dual) if reg == 2 else dual_pass_par_tv_tv(*dual))
                ss = (primal_pass_par_plain(*head, *tail) if data == PLAIN else primal_pass_par_quad(*head, *tail)
                      if data == QUAD else primal_pass_par_mass(*head, *tail) if data == MASS
                      else primal_pass_par_bc(*head, *tail))
            else:
                _ = (dual_pass_ser_l2(*dual) if reg == 0 else dual_pass_ser_tv(*dual) if reg == 1
                     else dual_pass_ser_tv_l2(*dual) if reg == 2 else dual_pass_ser_tv_tv(*dual))
                ss = (primal_pass_ser_plain(*head, *tail) if data == PLAIN else primal_pass_ser_quad(*head, *tail)
                      if data == QUAD else primal_pass_ser_mass(*head, *tail) if data == MASS
                      else primal_pass_ser_bc(*head, *tail))
            if measure and math.sqrt(ss / n) < tolerance:
                break
        return k

    iterate.__name__ = iterate.__qualname__ = "iterate" if data == PLAIN else "iterate_" + DATA_NAMES[data]
    return njit(**_JIT)(iterate)


iterate, iterate_quad, iterate_mass, iterate_bc = (_make_iterate(d) for d in (PLAIN, QUAD, MASS, BC))
ITERATE_NAMES = ("iterate", "iterate_quad", "iterate_mass", "iterate_bc")  # by data code: this module's kernels
