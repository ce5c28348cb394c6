"""The paper's models, each defined once: data term G, regulariser F(K .), the operator K and its adjoint,
the prox operators, the step sizes, and the energy (paper, "Primal-Dual Algorithm", Table "G, F, K").

Shapes (channel-first, see operators.py):
    v       (2, H, W)         flow, v[0] = u (x), v[1] = v (y), px/frame
    w       (2, 2, H, W)      auxiliary field of the extended models, same layout as grad(v): [dir, comp]
    y       (2, 2, H, W)      dual of grad v - w (or of grad v)
    z       (2, 2, 2, H, W)   dual of grad w (l1_tv_tv only)
    a, c    (2, H, W), (H, W) linearised data term rho(v) = a . v + c
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
    """rho(v) = a . v + c, the linearised optical flow constraint. -> (H, W)."""
    return a[0] * v[0] + a[1] * v[1] + c


def prox_data_l2(vt: np.ndarray, a: np.ndarray, c: np.ndarray, tau: float) -> np.ndarray:
    """argmin_v |v - vt|^2 / 2 + tau/2 rho(v)^2, pointwise closed form: vt - tau rho(vt) a / (1 + tau |a|^2)."""
    scale = tau * residual(vt, a, c) / (1.0 + tau * (a[0] ** 2 + a[1] ** 2))
    return vt - scale * a


def prox_data_l1(vt: np.ndarray, a: np.ndarray, c: np.ndarray, tau: float) -> np.ndarray:
    """argmin_v |v - vt|^2 / 2 + tau |rho(v)|, the paper's three-case thresholding.

    rho < -tau|a|^2: step +tau a; rho > tau|a|^2: step -tau a; else project onto rho = 0.
    Where |a| = 0 the data term is constant and vt is returned.
    """
    r = residual(vt, a, c)
    a2 = a[0] ** 2 + a[1] ** 2
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


def project_dual_tv(yt: np.ndarray, alpha: float, tv_norm: str) -> np.ndarray:
    """prox of sigma F* with F = alpha |.|_1: projection onto the dual-norm ball of radius alpha.

    isotropic: pointwise Euclidean ball over all leading components (the paper's "fully isotropic");
    anisotropic: componentwise clip to [-alpha, alpha] (max-norm ball). yt: (..., H, W).
    """
    if tv_norm == "anisotropic":
        return np.clip(yt, -alpha, alpha)
    lead = tuple(range(yt.ndim - 2))
    norm = np.sqrt(np.sum(yt * yt, axis=lead))
    return yt / np.maximum(1.0, norm / alpha)


def tv_norm_of(g: np.ndarray, tv_norm: str) -> float:
    """sum over pixels of |g(x)| in the primal norm (isotropic: Euclidean over components; anisotropic: l1)."""
    if tv_norm == "anisotropic":
        return float(np.abs(g).sum())
    lead = tuple(range(g.ndim - 2))
    return float(np.sqrt(np.sum(g * g, axis=lead)).sum())


# ------------------------------------------------------------------------------------------ K and K*
def apply_k(spec: ModelSpec, v: np.ndarray, w: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
    """K(v, w) = (grad v - w, grad w); for the gradient models K v = grad v (and no second block)."""
    gv = grad(v)
    if not spec.extended:
        return gv, None
    return gv - w, (grad(w) if spec.regulariser == "tv_tv" else None)


def apply_k_adjoint(spec: ModelSpec, y: np.ndarray, z: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
    """K*(y, z) = (-div y, -y - div z): the adjoint of :func:`apply_k` (w part None for gradient models)."""
    kv = -div(y)
    if not spec.extended:
        return kv, None
    kw = -y if z is None else -y - div(z)
    return kv, kw


# ------------------------------------------------------------------------------------------- energy
def energy(spec: ModelSpec, v: np.ndarray, w: np.ndarray | None, a: np.ndarray, c: np.ndarray,
           alpha: float, alpha1: float, tv_norm: str, q: np.ndarray | None = None) -> float:
    """The primal energy G + F(K .) of the model at (v, w) (sums over pixels, float64); with a quadratic
    data term ``q`` (:func:`prox_data_quadratic`) that one instead of the model's data term on (a, c)."""
    r = residual(v, a, c).astype(np.float64)
    if q is not None:
        data = quadratic_data(v, q)
    else:
        data = 0.5 * float(np.sum(r * r)) if spec.data == "l2" else float(np.abs(r).sum())
    k1, k2 = apply_k(spec, v.astype(np.float64), None if w is None else w.astype(np.float64))
    if spec.regulariser == "l2":
        reg = 0.5 * alpha * float(np.sum(k1 * k1))
    else:
        reg = alpha * tv_norm_of(k1, tv_norm)
    if spec.regulariser == "tv_l2":
        reg += 0.5 * alpha1 * float(np.sum(w.astype(np.float64) ** 2))
    elif spec.regulariser == "tv_tv":
        reg += alpha1 * tv_norm_of(k2, tv_norm)
    return data + reg
