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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .operators import div, grad


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
    m = weight if data == "l1" else np.sqrt(weight)
    return (a * m).astype(np.float32, copy=False), (c * m).astype(np.float32, copy=False)


def weight_quadratic(q: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """A quadratic data term (5, H, W) (:func:`prox_data_quadratic`) times the per-pixel weight m (H, W):
    m (v^T T v / 2 + g . v). -> float32 (5, H, W), a new array."""
    return (q * weight).astype(np.float32, copy=False)


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
def prox_dual_l2(yt: np.ndarray, sigma: float, alpha: float) -> np.ndarray:
    """prox of sigma F* with F = (alpha/2)|.|^2, F* = |y|^2 / (2 alpha): yt / (1 + sigma/alpha)."""
    return yt / (1.0 + sigma / alpha)


def project_dual_tv(yt: np.ndarray, alpha: float, tv_norm: str, spatial: int = 2) -> np.ndarray:
    """prox of sigma F* with F = alpha |.|_1: projection onto the dual-norm ball of radius alpha.

    isotropic: pointwise Euclidean ball over all leading components (the paper's "fully isotropic");
    anisotropic: componentwise clip to [-alpha, alpha] (max-norm ball). yt: (..., H, W), or (..., Z, Y, X)
    with ``spatial`` 3.
    """
    if tv_norm == "anisotropic":
        return np.clip(yt, -alpha, alpha)
    lead = tuple(range(yt.ndim - spatial))
    norm = np.sqrt(np.sum(yt * yt, axis=lead))
    return yt / np.maximum(1.0, norm / alpha)


def tv_norm_of(g: np.ndarray, tv_norm: str, spatial: int = 2) -> float:
    """sum over pixels of |g(x)| in the primal norm (isotropic: Euclidean over components; anisotropic: l1);
    the last ``spatial`` axes are the pixel grid."""
    if tv_norm == "anisotropic":
        return float(np.abs(g).sum())
    lead = tuple(range(g.ndim - spatial))
    return float(np.sqrt(np.sum(g * g, axis=lead)).sum())


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
# reached a given AEE in about half the iterations (bench.volume scenes at 48^3, 5 warps x 20 iterations: shift
# 0.041 -> 0.019 voxels, zoom and shear unchanged at 0.057 and 0.128; 0.25 was as good there but slower on
# a single level, test_volume's CLI case; 0.125 lost on shear). docs/engine.md, "Volumes".
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
def energy(spec: ModelSpec, v: np.ndarray, w: np.ndarray | None, a: np.ndarray, c: np.ndarray,
           alpha: float, alpha1: float, tv_norm: str, q: np.ndarray | None = None,
           incompressibility: float = 0.0) -> float:
    """The primal energy G + F(K .) of the model at (v, w) (sums over pixels, float64); with a quadratic
    data term ``q`` (:func:`prox_data_quadratic`) that one instead of the model's data term on (a, c); plus
    the incompressibility penalty (beta/2)|div v|^2 with beta = ``incompressibility``."""
    spatial = v.shape[0]
    r = residual(v, a, c).astype(np.float64)
    if q is not None:
        data = quadratic_data(v, q)
    else:
        data = 0.5 * float(np.sum(r * r)) if spec.data == "l2" else float(np.abs(r).sum())
    k1, k2 = apply_k(spec, v.astype(np.float64), None if w is None else w.astype(np.float64))
    if spec.regulariser == "l2":
        reg = 0.5 * alpha * float(np.sum(k1 * k1))
    else:
        reg = alpha * tv_norm_of(k1, tv_norm, spatial)
    if spec.regulariser == "tv_l2":
        reg += 0.5 * alpha1 * float(np.sum(w.astype(np.float64) ** 2))
    elif spec.regulariser == "tv_tv":
        reg += alpha1 * tv_norm_of(k2, tv_norm, spatial)
    if incompressibility > 0.0:
        reg += 0.5 * incompressibility * float(np.sum(flow_divergence(v.astype(np.float64)) ** 2))
    return data + reg
