"""The derived motion outputs' robust fits as numba kernels: :func:`fit_model_numba` (the dominant motion's
similarity and homography, :func:`flow_node.pipeline.motion.fit_model`) and :func:`region_fits_numba` (the
time to contact's affine fits, :func:`flow_node.pipeline.expansion.region_fits`). The numpy functions are the
reference and test oracle (test/test_fits_numba.py: the parameters to ~1e-9, the same inliers).

The reference runs the IRLS loop as ~150 small numpy calls (residual, masked quantile, weights, normal
equations, solve) whose overhead, not their arithmetic on ~1000 samples, is the cost (~0.3 ms a fit
whatever the image size); here one call runs the whole loop: the residual scale by the same lower quantile
(``np.partition`` of the kept residuals), the same weights and stopping rules, the model's normal equations as
weighted dot products summed in any order (:func:`_wdot`, reassociated so that LLVM vectorises them; the
rest in the reference's order, no fastmath), solved by Gaussian elimination with partial pivoting (p <= 8;
singular: a zero pivot, where numpy's LAPACK solve raises). At 320x240 (972 samples, a tight loop):
similarity 141 -> 36 us, homography 223 -> 74 us, the TTC's nine region fits 329 -> 80 us. A first version
that summed the normal equations sample by sample into a (p, p) array and sorted for the quantile was no
faster than numpy (109 and 219 us). Also the moving mask's deviating pixels, :func:`deviating_numba` (the
reference :func:`flow_node.pipeline.motion.deviating_pixels`, ~8 float32 numpy passes, 0.25-0.32 ms at 320x240):
one pass, 0.05 ms, the same bits (no fastmath; tested at the threshold's ulp). Selected with the engine's
backend (derived.fits_for); compiled by the node's warm-up (derived.warm_fits).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .motion import MaskThreshold, SampleFrame
from .robust import (
    CONVERGED_PX,
    HUBER_ITERATIONS,
    HUBER_K,
    MIN_SCALE_PX,
    START_CANDIDATES,
    START_CONFIDENCE,
    START_QUANTILE,
    TUKEY_C,
    TUKEY_ITERATIONS,
    RobustFit,
    Samples,
    medoid_spread,
    slope_span,
)

_JIT = dict(cache=True, nogil=True, error_model="numpy")  # no fastmath: the reference's arithmetic, in order
MODEL_CODES = {"similarity": 0, "homography": 1}  # SampleFrame's models -> the kernel's flag
_MAX_FLOAT = float(np.finfo(np.float64).max)  # what np.nan_to_num makes of inf
_SCALE_FACTOR = tuple(1.4826 * math.sqrt(math.log(2.0) / -math.log(1.0 - q)) for q in (0.5, START_QUANTILE))


@njit(**_JIT)
def _quantile(values, keep, q):  # noqa: ANN001, ANN202
    """robust.masked_quantile of values (n,) over keep (n,) bool: the lower ``q`` quantile, the entry of rank
    floor((k - 1) q) of the k kept (a selection: the reference's value exactly); NaN when none is kept."""
    kept = values[keep]
    if kept.size == 0:
        return np.nan
    k = int((kept.size - 1) * q)
    return np.partition(kept, k)[k]


@njit(**_JIT)
def _scale(residual, keep, q, factor):  # noqa: ANN001, ANN202
    """robust.robust_scale of residual (n,) over keep (n,) bool: factor x the lower ``q`` quantile
    (:func:`_quantile`), at least MIN_SCALE_PX (also when nothing is kept)."""
    kept = _quantile(residual, keep, q)
    return MIN_SCALE_PX if np.isnan(kept) else max(MIN_SCALE_PX, factor * kept)


@njit(**_JIT)
def _reweight(residual, conf, scale, tukey, weight):  # noqa: ANN001, ANN202
    """robust.reweight into ``weight`` (n,): conf x psi(r / s), psi Huber's or (``tukey``) the biweight; s
    from the START_QUANTILE quantile of the confident samples when ``scale`` < 0 (the first step), else
    the median of those within TUKEY_C previous scales. Returns s."""
    if scale < 0.0:
        s = _scale(residual, conf > 0.0, START_QUANTILE, _SCALE_FACTOR[1])
    else:
        s = _scale(residual, (conf > 0.0) & (residual < TUKEY_C * scale), 0.5, _SCALE_FACTOR[0])
    for i in range(residual.size):
        z = residual[i] / s
        if tukey:
            t = max(1.0 - (z / TUKEY_C) ** 2, 0.0)
            weight[i] = conf[i] * (t * t)
        else:
            weight[i] = conf[i] * min(1.0, HUBER_K / max(z, 1e-12))
    return s


@njit(cache=True, nogil=True, error_model="numpy", fastmath={"reassoc", "contract"})
def _wdot(a, b, w):  # noqa: ANN001, ANN202
    """sum(a * b * w) of three (m,) arrays, vectorised (reassociated: the sum in any order)."""
    acc = 0.0
    for k in range(a.size):
        acc += a[k] * b[k] * w[k]
    return acc


@njit(**_JIT)
def _solve(a, b):  # noqa: ANN001, ANN202
    """a x = b for a (p, p) and b (p, c) (both overwritten) by Gaussian elimination with partial pivoting;
    (x (p, c), True), or False when a pivot is 0 (singular)."""
    p = a.shape[0]
    for k in range(p):
        piv = k
        for i in range(k + 1, p):
            if abs(a[i, k]) > abs(a[piv, k]):
                piv = i
        if a[piv, k] == 0.0:
            return b, False
        if piv != k:
            for j in range(p):
                a[k, j], a[piv, j] = a[piv, j], a[k, j]
            for j in range(b.shape[1]):
                b[k, j], b[piv, j] = b[piv, j], b[k, j]
        for i in range(k + 1, p):
            f = a[i, k] / a[k, k]
            for j in range(k, p):
                a[i, j] -= f * a[k, j]
            for j in range(b.shape[1]):
                b[i, j] -= f * b[k, j]
    x = np.empty_like(b)
    for k in range(p - 1, -1, -1):
        for j in range(b.shape[1]):
            acc = b[k, j]
            for i in range(k + 1, p):
                acc -= a[k, i] * x[i, j]
            x[k, j] = acc / a[k, k]
    return x, True


@njit(**_JIT)
def _linearise(model, params, X, Y, half, flow, target, jac, err):  # noqa: ANN001, ANN202
    """SampleFrame.similarity (model 0) or SampleFrame.homography (1) at ``params`` into jac (p, 2n) and err (2n,)."""
    n = X.size
    if model == 0:
        tx, ty, a, b = params[0], params[1], params[2], params[3]
        for i in range(n):
            x, y = X[i] * half, Y[i] * half
            jac[0, i], jac[1, i], jac[2, i], jac[3, i] = half, 0.0, x, -y
            jac[0, n + i], jac[1, n + i], jac[2, n + i], jac[3, n + i] = 0.0, half, y, x
            err[i] = flow[i] - (tx * half + a * x - b * y)
            err[n + i] = flow[n + i] - (ty * half + a * y + b * x)
        return
    h = params
    for i in range(n):
        x, y = X[i], Y[i]
        inv = half / (h[6] * x + h[7] * y + 1.0)
        pu = (h[0] * x + h[1] * y + h[2]) * inv
        pv = (h[3] * x + h[4] * y + h[5]) * inv
        jac[0, i], jac[1, i], jac[2, i] = x * inv, y * inv, inv
        jac[3, i] = jac[4, i] = jac[5, i] = 0.0
        jac[0, n + i] = jac[1, n + i] = jac[2, n + i] = 0.0
        jac[3, n + i], jac[4, n + i], jac[5, n + i] = x * inv, y * inv, inv
        gu, gv = pu * (inv / -half), pv * (inv / -half)
        jac[6, i], jac[6, n + i], jac[7, i], jac[7, n + i] = x * gu, x * gv, y * gu, y * gv
        err[i], err[n + i] = target[i] - pu, target[n + i] - pv


@njit(**_JIT)
def _irls(model, start, X, Y, half, flow, target, conf, huber_iterations, tukey_iterations):  # noqa: ANN001, ANN202
    """robust.fit_robust of ``model`` (see :func:`_linearise`): (params, residual (n,), scale, ok)."""
    n, p = X.size, start.size
    params = start.copy()
    jac, err, moved_by = np.empty((p, 2 * n)), np.empty(2 * n), np.empty(2 * n)
    residual, weight, weight2 = np.empty(n), np.empty(n), np.empty(2 * n)
    _linearise(model, params, X, Y, half, flow, target, jac, err)
    scale = -1.0
    for stage in range(2):
        for _ in range(huber_iterations if stage == 0 else tukey_iterations):
            for i in range(n):
                residual[i] = math.sqrt(err[i] * err[i] + err[n + i] * err[n + i])
            scale = _reweight(residual, conf, scale, stage == 1, weight)
            weight2[:n], weight2[n:] = weight, weight  # both components of a sample weighted alike
            normal, rhs = np.empty((p, p)), np.empty((p, 1))  # robust._step
            for r in range(p):
                rhs[r, 0] = _wdot(jac[r], err, weight2)
                for c in range(r, p):
                    normal[r, c] = normal[c, r] = _wdot(jac[r], jac[c], weight2)
            trace = 0.0
            for r in range(p):
                trace += normal[r, r]
            if not (np.isfinite(trace) and trace > 0.0 and np.all(np.isfinite(normal))):
                return params, residual, 0.0, False
            for r in range(p):
                normal[r, r] += 1e-12 * trace
            step, solved = _solve(normal, rhs)
            if not (solved and np.all(np.isfinite(step))):
                return params, residual, 0.0, False
            moved_by[:] = 0.0  # step @ jac: each sample's model flow change, px
            for r in range(p):
                moved_by += step[r, 0] * jac[r]
            moved = np.max(np.abs(moved_by))
            for r in range(p):
                params[r] += step[r, 0]
            _linearise(model, params, X, Y, half, flow, target, jac, err)
            if moved < CONVERGED_PX:
                break
    for i in range(n):
        residual[i] = math.sqrt(err[i] * err[i] + err[n + i] * err[n + i])
    limit = np.inf if scale < 0.0 else TUKEY_C * scale
    final = _scale(residual, (conf > 0.0) & (residual < limit), 0.5, _SCALE_FACTOR[0])
    return params, residual, final, True


def fit_model_numba(model: str, frame: SampleFrame, start: np.ndarray, confidence: np.ndarray,
                    huber_iterations: int) -> RobustFit | None:
    """:func:`flow_node.pipeline.motion.fit_model` with one compiled call (the same arguments and result)."""
    params, residual, scale, ok = _irls(MODEL_CODES[model], np.asarray(start, np.float64), frame.X, frame.Y,
                                        float(frame.half), frame.flow, frame.target,
                                        np.ascontiguousarray(confidence, np.float64), huber_iterations,
                                        TUKEY_ITERATIONS)
    return RobustFit(params, residual, float(scale)) if ok else None


@njit(**_JIT)
def _median_slopes(u, v, x, y, keep, d, along_x):  # noqa: ANN001, ANN202
    """robust.median_slopes of the grids u and v (ny, nx) along x (``along_x``) or y, pairs ``d`` apart:
    (d u / d coord, d v / d coord), the medians (:func:`_quantile`) of the kept pairs' slopes; NaN without."""
    ny, nx = u.shape
    m = ny * (nx - d) if along_x else (ny - d) * nx
    su, sv, both = np.empty(m), np.empty(m), np.empty(m, np.bool_)
    k = 0
    for i in range(ny - (0 if along_x else d)):
        for j in range(nx - (d if along_x else 0)):
            i2, j2 = (i, j + d) if along_x else (i + d, j)
            dc = x[i2, j2] - x[i, j] if along_x else y[i2, j2] - y[i, j]
            both[k] = keep[i, j] and keep[i2, j2] and dc != 0.0
            div = dc if dc != 0.0 else 1.0
            su[k], sv[k] = (u[i2, j2] - u[i, j]) / div, (v[i2, j2] - v[i, j]) / div
            k += 1
    return _quantile(su, both, 0.5), _quantile(sv, both, 0.5)


@njit(**_JIT)
def _medoid(ru, rv, keep, idx, ref):  # noqa: ANN001, ANN202
    """robust.medoid_offset of the vectors (ru, rv) (m,) over keep (m,) bool with its candidates ``idx`` and
    references ``ref`` (robust.medoid_spread): the candidate of least median squared distance to the kept
    references, the reference's ties and edge cases alike (its np.nan_to_num: a candidate not kept scores
    the largest float, one without kept references inf; the first least); (0, 0) when nothing is kept."""
    if not np.any(keep):
        return 0.0, 0.0
    d, kept = np.empty(ref.size), np.empty(ref.size, np.bool_)
    best, best_score = 0, np.inf
    for a in range(idx.size):
        c = idx[a]
        if keep[c]:
            for b in range(ref.size):
                dx, dy = ru[ref[b]] - ru[c], rv[ref[b]] - rv[c]
                d[b], kept[b] = dx * dx + dy * dy, keep[ref[b]]
            score = _quantile(d, kept, 0.5)
            score = np.inf if np.isnan(score) else (_MAX_FLOAT if score == np.inf else score)
        else:
            score = _MAX_FLOAT
        if a == 0 or score < best_score:
            best, best_score = a, score
    return ru[idx[best]], rv[idx[best]]


@njit(**_JIT)
def _start(u, v, x, y, w, X, Y, half, dx, dy, idx, ref):  # noqa: ANN001, ANN202
    """motion.similarity_start: (tx, ty, a, b) normalised from the samples' grids u, v, x, y, w (ny, nx)
    and their normalised coordinates X, Y (ny nx,); ``dx``, ``dy`` the slopes' pair distances along x and y."""
    keep = w >= START_CONFIDENCE
    dudx, dvdx = _median_slopes(u, v, x, y, keep, dx, True)
    dudy, dvdy = _median_slopes(u, v, x, y, keep, dy, False)
    a, b = (dudx + dvdy) / 2.0, (dvdx - dudy) / 2.0
    a, b = 0.0 if np.isnan(a) else a, 0.0 if np.isnan(b) else b
    n = X.size
    ru, rv = np.empty(n), np.empty(n)
    uf, vf, kf = u.ravel(), v.ravel(), keep.ravel()
    for i in range(n):
        xh, yh = X[i] * half, Y[i] * half
        ru[i] = uf[i] - a * xh + b * yh
        rv[i] = vf[i] - b * xh - a * yh
    tx, ty = _medoid(ru, rv, kf, idx, ref)
    out = np.empty(4)
    out[0], out[1], out[2], out[3] = tx / half, ty / half, a, b
    return out


def similarity_start_numba(frame: SampleFrame) -> np.ndarray:
    """:func:`flow_node.pipeline.motion.similarity_start` in one compiled call (the same argument and result:
    (tx, ty, a, b) normalised, the reference's values exactly: the same selections and arithmetic)."""
    s = frame.s
    ny, nx = s.u.shape
    idx, ref = medoid_spread(ny * nx, START_CANDIDATES)
    grids = (np.ascontiguousarray(g, np.float64) for g in (s.u, s.v, s.x, s.y, s.w))
    return _start(*grids, frame.X, frame.Y, float(frame.half), slope_span(nx), slope_span(ny), idx, ref)


@njit(**_JIT)
def _regions(X, Y, uv, conf, start, huber_iterations, tukey_iterations):  # noqa: ANN001, ANN202
    """expansion.region_fits: (coef (R, 3, 2), ok (R,))."""
    count, m = X.shape
    coef, ok = start.copy(), np.ones(count, np.bool_)
    scale = np.full(count, -1.0)
    residual, weight = np.empty(m), np.empty(m)
    for stage in range(2):
        for _ in range(huber_iterations if stage == 0 else tukey_iterations):
            change = 0.0
            for r in range(count):
                for i in range(m):  # expansion._affine_residual
                    du = uv[r, i, 0] - (coef[r, 0, 0] + X[r, i] * coef[r, 1, 0] + Y[r, i] * coef[r, 2, 0])
                    dv = uv[r, i, 1] - (coef[r, 0, 1] + X[r, i] * coef[r, 1, 1] + Y[r, i] * coef[r, 2, 1])
                    residual[i] = math.sqrt(du * du + dv * dv)
                scale[r] = _reweight(residual, conf[r], scale[r], stage == 1, weight)
                normal, rhs = np.zeros((3, 3)), np.zeros((3, 2))  # expansion._affine_fits
                for i in range(m):
                    b = (1.0, X[r, i], Y[r, i])
                    for j in range(3):
                        wb = b[j] * weight[i]
                        rhs[j, 0] += wb * uv[r, i, 0]
                        rhs[j, 1] += wb * uv[r, i, 1]
                        for k in range(3):
                            normal[j, k] += wb * b[k]
                det = (normal[0, 0] * (normal[1, 1] * normal[2, 2] - normal[1, 2] * normal[2, 1])
                       - normal[0, 1] * (normal[1, 0] * normal[2, 2] - normal[1, 2] * normal[2, 0])
                       + normal[0, 2] * (normal[1, 0] * normal[2, 1] - normal[1, 1] * normal[2, 0]))
                ok[r] = det > 1e-9 * max(normal[0, 0], 1e-30) ** 3
                new, solved = _solve(normal, rhs)
                if not (ok[r] and solved):
                    ok[r], new = False, np.zeros((3, 2))
                for c in range(2):
                    moved = 0.0
                    for j in range(3):
                        moved += abs(new[j, c] - coef[r, j, c])
                        coef[r, j, c] = new[j, c]
                    change = max(change, moved)
            if change < CONVERGED_PX:
                break
    return coef, ok


def region_fits_numba(X: np.ndarray, Y: np.ndarray, uv: np.ndarray, conf: np.ndarray,
                      start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`flow_node.pipeline.expansion.region_fits` with one compiled call (the same arguments and
    result)."""
    f64 = (np.ascontiguousarray(a, np.float64) for a in (X, Y, uv, conf, start))
    return _regions(*f64, HUBER_ITERATIONS, TUKEY_ITERATIONS)


@njit(**_JIT)
def _deviating(out, flow, hm, w, abs_px, rel):  # noqa: ANN001, ANN202
    """motion.deviating_pixels into ``out`` (h w,) bool of flat ``flow`` (h w 2,) u, v interleaved, rows of
    ``w``: one pass, each float32 step of the reference in its order (no fastmath: no fused multiply-add,
    np.sqrt correctly rounded, as numpy's), so the same bits. Flat arrays and the homography in locals so
    that LLVM vectorises the rows (with 2-D views it did not: 0.38 vs 0.04 ms at 320x240)."""
    h00, h01, h02, h10, h11, h12, h20, h21, h22 = (hm[0, 0], hm[0, 1], hm[0, 2], hm[1, 0], hm[1, 1], hm[1, 2],
                                                   hm[2, 0], hm[2, 1], hm[2, 2])
    for i in range(out.size // w):
        y = np.float32(i)
        ru, rv, rd = h01 * y, h11 * y, h21 * y  # the row terms of the numerators and the denominator
        base = i * w
        for j in range(w):
            x = np.float32(j)
            den = (h20 * x + h22) + rd
            pu = ((h00 * x + h02) + ru) / den - x
            pv = ((h10 * x + h12) + rv) / den - y
            limit = np.sqrt(pu * pu + pv * pv) * rel + abs_px
            du, dv = flow[2 * (base + j)] - pu, flow[2 * (base + j) + 1] - pv
            out[base + j] = np.sqrt(du * du + dv * dv) > limit


def deviating_numba(flow: np.ndarray, hm: np.ndarray, abs_px: np.float32, rel: np.float32) -> np.ndarray:
    """:func:`flow_node.pipeline.motion.deviating_pixels` in one compiled pass (the same arguments: flow
    (H, W, 2) px/frame, homography (3x3) on pixels, the threshold's abs px and rel; the same bool (H, W))."""
    h, w = flow.shape[:2]
    out = np.empty(h * w, np.bool_)
    _deviating(out, np.ascontiguousarray(flow, dtype=np.float32).reshape(-1),
               np.ascontiguousarray(hm, dtype=np.float32), w, np.float32(abs_px), np.float32(rel))
    return out.reshape(h, w)


@njit(**_JIT)
def _inliers(out, hp, x, y, u, v, abs_px, rel):  # noqa: ANN001, ANN202
    """motion.sample_inliers into ``out`` (n,) bool of the samples x, y, u, v (n,): apply_homography and
    MaskThreshold.deviates per sample, each float64 step in the reference's order (the same bits)."""
    for i in range(out.size):
        den = hp[2, 0] * x[i] + hp[2, 1] * y[i] + hp[2, 2]
        pu = (hp[0, 0] * x[i] + hp[0, 1] * y[i] + hp[0, 2]) / den - x[i]
        pv = (hp[1, 0] * x[i] + hp[1, 1] * y[i] + hp[1, 2]) / den - y[i]
        du, dv = u[i] - pu, v[i] - pv
        limit = abs_px + rel * np.sqrt(pu * pu + pv * pv)
        out[i] = not (du * du + dv * dv > limit * limit)


def sample_inliers_numba(hp: np.ndarray, s: Samples, threshold: MaskThreshold) -> np.ndarray:
    """:func:`flow_node.pipeline.motion.sample_inliers` in one compiled pass (the same arguments, the same
    bool (ny, nx))."""
    out = np.empty(s.x.shape, np.bool_)
    flat = (np.ascontiguousarray(a, np.float64).reshape(-1) for a in (s.x, s.y, s.u, s.v))
    _inliers(out.reshape(-1), np.ascontiguousarray(hp, np.float64), *flat, float(threshold.abs_px),
             float(threshold.rel))
    return out


def compiled() -> bool:
    """Whether the kernels are compiled (or loaded from numba's cache) in this process (derived.warm_fits)."""
    return bool(_irls.signatures and _regions.signatures and _deviating.signatures and _start.signatures
                and _inliers.signatures)
