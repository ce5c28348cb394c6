"""The paper's models, each defined once: data term G, regulariser F(K .), the operator K and its adjoint,
the prox operators, the step sizes, and the energy (paper, "Primal-Dual Algorithm", Table "G, F, K").

Shapes (channel-first, see operators.py), for an image; on a volume every "2" is a 3 and (H, W) is (Z, Y, X)
(the operators and prox operators below take either; the census term's quadratic form is 2-D only):
    v       (2, H, W)         flow, v[0] = u (x), v[1] = v (y), px/frame
    w       (2, 2, H, W)      auxiliary field of the extended models, same layout as grad(v): [dir, comp]
    y       (2, 2, H, W)      dual of grad v - w (or of grad v)
    z       (2, 2, 2, H, W)   dual of grad w (l1_tv_tv only)
    a, c    (2, H, W), (H, W) linearised data term rho(v) = a . v + c
    s       (H, W)            dual of div v (the incompressibility penalty, volumes)
    m       (2, 2, H, W)      mass preservation: rho(v) = a . v + M : grad v + c, A v = a . v + M : grad v
    p       (H, W)            dual of the data term A v + c (mass preservation only, where the data is dualised)
    ab, cb  (2, H, W), (H, W) mass preservation's brightness term beside it: ab . v + cb (prox_data_metric)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .operators import div, grad, jacobian_central, jacobian_central_adjoint


@dataclass(frozen=True)
class ModelSpec:
    """What distinguishes the five models: the data term and the regulariser (and their step sizes)."""

    name: str
    data: str  # "l2": (1/2)|rho|^2, "l1": |rho|
    regulariser: str  # "l2": (a/2)|grad v|^2, "tv": a|grad v|, "tv_l2", "tv_tv" (extended, with w)
    tau: float  # primal step (paper: 1/4 gradient models, 1/5 extended models)
    sigma: float  # dual step (paper: 1/2 gradient models, 1/3 extended models)

    @property
    def extended(self) -> bool:
        return self.regulariser in ("tv_l2", "tv_tv")


MODEL_SPECS: dict[str, ModelSpec] = {
    "l2_l2": ModelSpec("l2_l2", "l2", "l2", 0.25, 0.5),
    "l2_tv": ModelSpec("l2_tv", "l2", "tv", 0.25, 0.5),
    "l1_tv": ModelSpec("l1_tv", "l1", "tv", 0.25, 0.5),
    "l1_tv_l2": ModelSpec("l1_tv_l2", "l1", "tv_l2", 0.2, 1.0 / 3.0),
    "l1_tv_tv": ModelSpec("l1_tv_tv", "l1", "tv_tv", 0.2, 1.0 / 3.0),
}


# The data term's constraint (FlowConfig.constraint): brightness constancy I1(x + v) = I0(x), or mass
# preservation I_t + div(I v) = 0, in the warping scheme I1(x + v) det(Id + grad v) = I0(x).
CONSTRAINTS = ("brightness", "mass")


# ------------------------------------------------------------------------------------------ data terms
def residual(v: np.ndarray, a: np.ndarray, c: np.ndarray) -> np.ndarray:
    """rho(v) = a . v + c, the linearised optical flow constraint. v, a: (dims, ...) -> (...)."""
    r = a[0] * v[0]
    for k in range(1, v.shape[0]):
        r += a[k] * v[k]
    return r + c


def _norm2(a: np.ndarray) -> np.ndarray:
    """|a|^2 over the components (axis 0)."""
    return np.sum(a * a, axis=0)


def prox_data_l2(vt: np.ndarray, a: np.ndarray, c: np.ndarray, tau: float) -> np.ndarray:
    """argmin_v |v - vt|^2 / 2 + tau/2 rho(v)^2, pointwise closed form: vt - tau rho(vt) a / (1 + tau |a|^2)."""
    scale = tau * residual(vt, a, c) / (1.0 + tau * _norm2(a))
    return vt - scale * a


def prox_data_l1(vt: np.ndarray, a: np.ndarray, c: np.ndarray, tau: float) -> np.ndarray:
    """argmin_v |v - vt|^2 / 2 + tau |rho(v)|, the paper's three-case thresholding.

    rho < -tau|a|^2: step +tau a; rho > tau|a|^2: step -tau a; else project onto rho = 0.
    Where |a| = 0 the data term is constant and vt is returned.
    """
    r = residual(vt, a, c)
    a2 = _norm2(a)
    ta2 = tau * a2
    step = np.where(r < -ta2, tau, np.where(r > ta2, -tau, -r / np.maximum(a2, 1e-12)))
    return vt + step * a


PROX_DATA = {"l2": prox_data_l2, "l1": prox_data_l1}


def joint_data(rho: np.ndarray, gamma: float) -> np.ndarray:
    """The joint model's data term of the flow (joint.py): J_gamma(rho) = rho^2 / (4 gamma) for |rho| <= 2 gamma,
    |rho| - gamma beyond, i.e. (1/gamma) min over the images u of D(u, f) + gamma C(u, v) at one pixel.
    -> rho's shape."""
    r = np.abs(rho)
    return np.where(r <= 2.0 * gamma, r * r / (4.0 * gamma), r - gamma)


def prox_data_joint(vt: np.ndarray, a: np.ndarray, c: np.ndarray, tau: float, gamma: float) -> np.ndarray:
    """argmin_v |v - vt|^2 / 2 + tau J_gamma(rho(v)) (:func:`joint_data`): the step along a is
    -tau J'(rho) = clip(-rho(vt) / (|a|^2 + 2 gamma / tau), -tau, tau) (quadratic part inside, L1 part outside);
    gamma -> 0 gives :func:`prox_data_l1`."""
    r = residual(vt, a, c)
    a2 = a[0] ** 2 + a[1] ** 2
    step = np.clip(-r / np.maximum(a2 + 2.0 * gamma / tau, 1e-12), -tau, tau)
    return vt + step * a


def weight_data(a: np.ndarray, c: np.ndarray, weight: np.ndarray, data: str) -> tuple[np.ndarray, np.ndarray]:
    """The linearised data term with a per-pixel weight m (H, W) in [0, 1] (the validity mask, validity.py):
    m |rho| = |m a . v + m c| for ``data`` "l1", (m/2) rho^2 = (1/2)(sqrt(m) a . v + sqrt(m) c)^2 for "l2".
    Folded into (a, c), so every prox above (and the numba kernels') applies it unchanged: prox of tau m D on
    (a, c) is prox of tau D on the weighted pair (a test checks both). m = 0 removes the pixel's data term.
    -> (a, c) new float32 arrays."""
    return weight_coefficient(a, weight, data), weight_coefficient(c, weight, data)


def weight_coefficient(x: np.ndarray, weight: np.ndarray, data: str) -> np.ndarray:
    """One coefficient array of a linear residual (a (2, H, W), c (H, W), or the mass term's M (2, 2, H, W))
    times the factor of :func:`weight_data`: m for ``data`` "l1", sqrt(m) for "l2" (the residual is linear in
    its coefficients, so weighting them all weights it). -> new float32 array of x's shape."""
    factor = weight if data == "l1" else np.sqrt(weight)
    return (x * factor).astype(np.float32, copy=False)


def weight_quadratic(q: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """A quadratic data term (5, H, W) (:func:`prox_data_quadratic`) times the per-pixel weight m (H, W):
    m (v^T T v / 2 + g . v). -> float32 (5, H, W), a new array."""
    return (q * weight).astype(np.float32, copy=False)


# ------------------------------------------------------------------- mass preservation (continuity equation)
def apply_a(v: np.ndarray, a: np.ndarray, m: np.ndarray) -> np.ndarray:
    """A v = a . v + M : grad v, the linearised continuity equation I_t + div(I v) = 0 without its constant
    (operators.mass_linearise: the warped Lagrangian form I1(x + v) det(Id + grad v) = I0(x) to first order,
    M = I1w cof(Id + grad v0), = I1w Id without warping, i.e. M : grad v = I1w div v; grad v the central
    differences of operators.jacobian_central). v (2, H, W), a (2, H, W), m (2, 2, H, W) -> (H, W)."""
    return a[0] * v[0] + a[1] * v[1] + np.sum(m * jacobian_central(v), axis=(0, 1))


def apply_a_adjoint(p: np.ndarray, a: np.ndarray, m: np.ndarray) -> np.ndarray:
    """A* p = a p + J*(M p), the adjoint of :func:`apply_a` (J* = operators.jacobian_central_adjoint).
    p (H, W) -> (2, H, W)."""
    return a * p + jacobian_central_adjoint(m * p)


def mass_residual(v: np.ndarray, a: np.ndarray, m: np.ndarray, c: np.ndarray) -> np.ndarray:
    """rho(v) = A v + c, the linearised mass-preservation residual. -> (H, W)."""
    return apply_a(v, a, m) + c


def prox_data_metric(vt: np.ndarray, a: np.ndarray, c: np.ndarray, t: np.ndarray, lam: float, data: str
                     ) -> np.ndarray:
    """argmin_v sum_k (v_k - vt_k)^2 / (2 t_k) + lam D(rho(v)), rho = a . v + c, D = |.| (l1) or (1/2)(.)^2 (l2):
    the prox of a pointwise data term in the metric of per-pixel, per-component steps t (2, H, W) (the mass
    problem's diagonal preconditioning, :func:`mass_steps`). v = vt + s T a with q = a . T a,
    s = clip(-rho(vt) / q, -lam, lam) for l1 and s = -lam rho(vt) / (1 + lam q) for l2; t = tau (all) gives
    :func:`prox_data_l1` / :func:`prox_data_l2` with tau lam. The brightness-constancy term beside the mass term
    (Problem.ab, cb; FlowConfig.mass_brightness). -> (2, H, W)."""
    r = residual(vt, a, c)
    q = t[0] * a[0] * a[0] + t[1] * a[1] * a[1]
    s = np.clip(-r / np.maximum(q, 1e-12), -lam, lam) if data == "l1" else -(lam * r / (1.0 + lam * q))
    return vt + s * t * a


def prox_dual_data(pt: np.ndarray, sigma: np.ndarray, lam: float, data: str) -> np.ndarray:
    """prox of sigma D* for the data term D(s) = lam |s| (l1: clip to [-lam, lam]) or (lam/2) s^2 (l2:
    pt / (1 + sigma / lam)); the constant c enters the argument: pt = p + sigma (A v_bar + c). sigma is
    per pixel (H, W) (:func:`mass_steps`)."""
    if data == "l1":
        return np.clip(pt, -lam, lam)
    return pt / (1.0 + sigma / lam)


def affine_modes(shape: tuple[int, int]) -> np.ndarray:
    """The six affine flow fields (6, 2, H, W) float32: constant u, constant v, and u, v each times the
    centred coordinates x / W and y / H (so every field's values stay within +-1/2)."""
    h, w = shape
    xs = np.broadcast_to((np.arange(w) - (w - 1) / 2.0)[None, :] / w, (h, w))
    ys = np.broadcast_to((np.arange(h) - (h - 1) / 2.0)[:, None] / h, (h, w))
    one = np.ones((h, w))
    out = np.zeros((6, 2, h, w), np.float32)
    for j, (k, f) in enumerate(((0, one), (1, one), (0, xs), (0, ys), (1, xs), (1, ys))):
        out[j, k] = f
    return out


def mode_step(phi: np.ndarray, r: np.ndarray, data: str, sweeps: int = 8, stride: int = 2) -> np.ndarray:
    """theta minimising the data term sum D(r + sum_j theta_j phi_j) over a few modes, fitted on every
    ``stride``-th pixel per axis: L2 by the normal equations, L1 by iteratively reweighted least squares
    (``sweeps``). phi (J, H, W) the data operator applied to each mode (A e_j), r (H, W) the residual at the
    current flow -> theta (J,) float64; zeros when the modes are not determined by the data (singular normal
    matrix)."""
    sub = phi[:, ::stride, ::stride]
    f64 = np.ascontiguousarray(sub.reshape(sub.shape[0], -1), dtype=np.float64)
    r64 = np.ascontiguousarray(r[::stride, ::stride].reshape(-1), dtype=np.float64)
    theta = np.zeros(phi.shape[0])
    for _ in range(1 if data == "l2" else sweeps):
        wgt = np.ones_like(r64) if data == "l2" else 1.0 / np.maximum(np.abs(r64 + theta @ f64), 1e-4)
        fw = f64 * wgt
        mat = fw @ f64.T
        if np.linalg.cond(mat) > 1e10:
            return np.zeros(phi.shape[0])
        theta = np.linalg.solve(mat, -(fw @ r64))
    return theta


def mass_steps(a: np.ndarray, m: np.ndarray, tau: float, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Diagonal preconditioning (Pock & Chambolle, ICCV 2011, alpha = 1) of K = [regulariser; s A]: the data
    dual's step sigma_p = s / (row sum of |A|) = s / (|a0| + |a1| + sum |M_kl|) and the flow's per-pixel
    step tau_v = 1 / (1 / tau + s * column sum of |A|), column sum of component k bounded by |a_k| +
    sum_l max(|M_kl(x - e_l)|, |M_kl(x + e_l)|); tau is the model's step (the regulariser's column sum:
    without data this is the paper's tau). s = ``scale`` > 0 weighs the data row (any s converges).
    -> sigma_p (H, W), tau_v (2, H, W)."""
    am = np.abs(m)
    row = np.abs(a[0]) + np.abs(a[1]) + np.sum(am, axis=(0, 1))
    sigma_p = scale / np.maximum(row, 1e-6)
    nx = np.maximum(np.concatenate([am[:, 0, :, 1:], am[:, 0, :, -1:]], axis=-1),
                    np.concatenate([am[:, 0, :, :1], am[:, 0, :, :-1]], axis=-1))
    ny = np.maximum(np.concatenate([am[:, 1, 1:], am[:, 1, -1:]], axis=-2),
                    np.concatenate([am[:, 1, :1], am[:, 1, :-1]], axis=-2))
    tau_v = 1.0 / (1.0 / tau + scale * (np.abs(a) + nx + ny))
    return sigma_p.astype(np.float32), tau_v.astype(np.float32)


def prox_data_quadratic(vt: np.ndarray, q: np.ndarray, tau: float) -> np.ndarray:
    """argmin_v |v - vt|^2 / 2 + tau (v^T T v / 2 + g . v) for a per-pixel quadratic data term (the census
    data term collapsed over its channels, census.py): q (5, H, W) = (T11, T12, T22, g1, g2), T positive
    semi-definite. Pointwise 2 x 2 solve: (I + tau T) v = vt - tau g."""
    m00, m01, m11 = 1.0 + tau * q[0], tau * q[1], 1.0 + tau * q[2]
    r0, r1 = vt[0] - tau * q[3], vt[1] - tau * q[4]
    det = m00 * m11 - m01 * m01
    return np.stack([(m11 * r0 - m01 * r1) / det, (m00 * r1 - m01 * r0) / det])


def quadratic_data(v: np.ndarray, q: np.ndarray) -> float:
    """v^T T v / 2 + g . v summed over pixels (the quadratic data term of :func:`prox_data_quadratic`)."""
    v, q = v.astype(np.float64), q.astype(np.float64)
    return float(np.sum(0.5 * (q[0] * v[0] ** 2 + 2 * q[1] * v[0] * v[1] + q[2] * v[1] ** 2)
                        + q[3] * v[0] + q[4] * v[1]))


# ------------------------------------------------------------------------------- regulariser (dual side)
def prox_dual_l2(yt: np.ndarray, sigma: float, alpha: float | np.ndarray) -> np.ndarray:
    """prox of sigma F* with F = (alpha/2)|.|^2, F* = |y|^2 / (2 alpha): yt / (1 + sigma/alpha) (alpha may be
    per pixel)."""
    return yt / (1.0 + sigma / alpha)


def project_dual_tv(yt: np.ndarray, alpha: float | np.ndarray, tv_norm: str, spatial: int = 2) -> np.ndarray:
    """prox of sigma F* with F = alpha |.|_1: projection onto the dual-norm ball of radius alpha; ``alpha`` may
    be per pixel (an array of the grid's shape: the edge-weighted TV sum_x g(x) |grad v(x)|, edges.py).

    isotropic: pointwise Euclidean ball over all leading components (the paper's "fully isotropic");
    anisotropic: componentwise clip to [-alpha, alpha] (max-norm ball). yt: (..., H, W), or (..., Z, Y, X)
    with ``spatial`` 3.
    """
    if tv_norm == "anisotropic":
        return np.clip(yt, -alpha, alpha)
    lead = tuple(range(yt.ndim - spatial))
    norm = np.sqrt(np.sum(yt * yt, axis=lead))
    return yt / np.maximum(1.0, norm / alpha)


def tv_norm_of(g: np.ndarray, tv_norm: str, spatial: int = 2, weight: np.ndarray | None = None) -> float:
    """sum over pixels of |g(x)| in the primal norm (isotropic: Euclidean over components; anisotropic: l1),
    each pixel's times ``weight`` (the grid's shape: the edge-weighted TV, edges.py; None: 1); the last ``spatial``
    axes are the pixel grid."""
    if tv_norm == "anisotropic" and weight is None:
        return float(np.abs(g).sum())
    lead = tuple(range(g.ndim - spatial))
    per_pixel = np.abs(g).sum(axis=lead) if tv_norm == "anisotropic" else np.sqrt(np.sum(g * g, axis=lead))
    return float(per_pixel.sum() if weight is None else np.sum(weight * per_pixel))


# ------------------------------------------------------------------- incompressibility (volumes, docs/engine.md)
def flow_divergence(v: np.ndarray) -> np.ndarray:
    """div v = sum_k d_k v_k with the forward differences of K (the trace of grad v), zero across the far
    border of each direction, so a constant flow has div v = 0 everywhere. v: (dims, ...) -> (...) 1/frame."""
    g = grad(v, dims=v.shape[0])
    return sum(g[k, k] for k in range(v.shape[0]))


def flow_divergence_adjoint(s: np.ndarray, dims: int) -> np.ndarray:
    """The adjoint of :func:`flow_divergence`: -div of the diagonal field p[k, k] = s. s: (...) -> (dims, ...)."""
    p = np.zeros((dims, dims) + s.shape, dtype=s.dtype)
    for k in range(dims):
        p[k, k] = s
    return -div(p)


def prox_dual_incompressibility(st: np.ndarray, sigma: float, beta: float) -> np.ndarray:
    """prox of sigma F* with F(s) = (beta/2)|s|^2 (the penalty on div v): st / (1 + sigma/beta)."""
    return st / (1.0 + sigma / beta)


def norm_bound(spec: ModelSpec, dims: int, incompressible: bool) -> float:
    """An upper bound of ||K||^2 on a ``dims``-D grid: |grad|^2 <= 4 dims per component, the div v block
    adds at most 4 dims; for the extended models ||grad v - w||^2 + ||grad w||^2 <= (1+e) Lv |v|^2 +
    (1 + 1/e + Lw) |w|^2 with e balancing the two."""
    lv = 4.0 * dims * (2.0 if incompressible else 1.0)
    if not spec.extended:
        return lv
    lw = 4.0 * dims if spec.regulariser == "tv_tv" else 0.0
    b = lv - 1.0 - lw
    e = (-b + (b * b + 4.0 * lv) ** 0.5) / (2.0 * lv)
    return (1.0 + e) * lv


# On volumes tau is multiplied by this and sigma divided by it (tau * sigma unchanged): a smaller primal step
# reached a given AEE in about half the iterations (the retired bench.volume's scenes at 48^3, 5 warps x 20
# iterations: shift 0.041 -> 0.019 voxels, zoom and shear unchanged at 0.057 and 0.128; 0.25 was as good there
# but slower on a single level, test_volume's CLI case; 0.125 lost on shear). docs/engine.md, "Volumes".
VOLUME_STEP_BALANCE = 0.5


def step_sizes(spec: ModelSpec, dims: int = 2, incompressible: bool = False) -> tuple[float, float]:
    """(tau, sigma) of the primal-dual iteration: the paper's (spec.tau, spec.sigma) on images; on a volume, or
    with the incompressibility block, sigma shrinks by the ratio of :func:`norm_bound` to the paper's case,
    so tau * sigma * ||K||^2 stays what the paper chose; on a volume, then, VOLUME_STEP_BALANCE moves step
    length from the primal to the dual side."""
    ratio = norm_bound(spec, 2, False) / norm_bound(spec, dims, incompressible)
    balance = VOLUME_STEP_BALANCE if dims == 3 else 1.0
    return spec.tau * balance, spec.sigma * ratio / balance


# ------------------------------------------------------------------------------------------ K and K*
def apply_k(spec: ModelSpec, v: np.ndarray, w: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
    """K(v, w) = (grad v - w, grad w); for the gradient models K v = grad v (and no second block)."""
    dims = v.shape[0]
    gv = grad(v, dims=dims)
    if not spec.extended:
        return gv, None
    return gv - w, (grad(w, dims=dims) if spec.regulariser == "tv_tv" else None)


def apply_k_adjoint(spec: ModelSpec, y: np.ndarray, z: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
    """K*(y, z) = (-div y, -y - div z): the adjoint of :func:`apply_k` (w part None for gradient models)."""
    kv = -div(y)
    if not spec.extended:
        return kv, None
    kw = -y if z is None else -y - div(z)
    return kv, kw


# ------------------------------------------------------------------------------------------- energy
def data_penalty(r: np.ndarray, data: str) -> float:
    """The data term's sum over pixels of a residual r: (1/2) sum r^2 for ``data`` "l2", sum |r| for "l1"."""
    return 0.5 * float(np.sum(r * r)) if data == "l2" else float(np.abs(r).sum())


def energy(spec: ModelSpec, v: np.ndarray, w: np.ndarray | None, a: np.ndarray, c: np.ndarray,
           alpha: float, alpha1: float, tv_norm: str, q: np.ndarray | None = None,
           incompressibility: float = 0.0, m: np.ndarray | None = None,
           bc: tuple[np.ndarray, np.ndarray] | None = None, weight: np.ndarray | None = None) -> float:
    """The primal energy G + F(K .) of the model at (v, w) (sums over pixels, float64); with a quadratic
    data term ``q`` (:func:`prox_data_quadratic`) that one instead of the model's data term on (a, c); with
    ``m`` the mass-preservation residual (:func:`mass_residual`), and with ``bc`` = (ab, cb) the model's data
    term on the brightness residual ab . v + cb added (its weight folded in, :func:`weight_data`); plus the
    incompressibility penalty (beta/2)|div v|^2 with beta = ``incompressibility``. ``weight``: the edge weight g
    (H, W) of the first regulariser term (solver.Problem.g; None: 1)."""
    spatial = v.shape[0]
    r = (residual(v, a, c) if m is None else mass_residual(v.astype(np.float64), a, m, c)).astype(np.float64)
    if q is not None:
        data = quadratic_data(v, q)
    else:
        data = data_penalty(r, spec.data)
    if bc is not None:
        data += data_penalty(residual(v.astype(np.float64), *bc), spec.data)
    k1, k2 = apply_k(spec, v.astype(np.float64), None if w is None else w.astype(np.float64))
    if spec.regulariser == "l2":
        reg = 0.5 * alpha * float(np.sum(k1 * k1 if weight is None else weight * k1 * k1))
    else:
        reg = alpha * tv_norm_of(k1, tv_norm, spatial, weight)
    if spec.regulariser == "tv_l2":
        reg += 0.5 * alpha1 * float(np.sum(w.astype(np.float64) ** 2))
    elif spec.regulariser == "tv_tv":
        reg += alpha1 * tv_norm_of(k2, tv_norm, spatial)
    if incompressibility > 0.0:
        reg += 0.5 * incompressibility * float(np.sum(flow_divergence(v.astype(np.float64)) ** 2))
    return data + reg
