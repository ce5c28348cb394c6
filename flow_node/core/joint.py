"""The paper's joint model (section "Joint Models" of its outlook): motion estimation and image reconstruction
together, for noisy or missing data.

    min_{u, v}  D(u, f) + alpha R(u) + beta S(v) + gamma C(u, v)

with the paper's names: f = (f0, f1) the measured frames, u = (u0, u1) the unknown images, v the flow. Our
choices:

* D(u, f) = 1/2 sum_k sum_x m_k(x) (u_k(x) - f_k(x))^2, m_k the validity masks (validity.py; 1 without one);
* R(u) = TV(u0) + TV(u1), isotropic;
* S(v) = the flow's regulariser of ``cfg.model`` (beta / gamma is ``cfg.alpha``);
* C(u, v) = sum_x |u1(x + v(x)) - u0(x)|: brightness constancy (the L1 data term of the flow models).

The flow (``cfg.reconstruction`` "joint"): with alpha = 0 and C taken pixel by pixel, the images can be
eliminated in closed form. At one pixel, with d = f1(x + v) - f0(x) and a = u1(x + v) - u0(x):
min over u of 1/2 (u0 - f0)^2 + 1/2 (u1 - f1)^2 subject to the difference a is (d - a)^2 / 4, and
min_a (d - a)^2 / 4 + gamma |a| is gamma J_gamma(d) with

    J_gamma(d) = d^2 / (4 gamma)  for |d| <= 2 gamma,   |d| - gamma  beyond   (models.joint_data)

(the images agree along the flow, a = 0, where the frames differ by less than 2 gamma: there the two noisy
measurements are averaged; beyond, each moves gamma towards the other). So the flow minimises
J_gamma(rho(v)) + (beta / gamma) S(v) -- the L1 data term with its kink rounded off over the noise's scale
-- solved by the same primal-dual scheme with the prox :func:`flow_node.core.models.prox_data_joint` (numba:
``numba_kernels.prox_data`` with ``soft`` = 2 gamma / tau). Alternating instead between the flow for fixed u
and u for fixed v (:func:`reconstruct`) was tried first and locks in: u made consistent with the current
flow leaves the flow step no residual to move on (docs/engine.md, "Joint model", measured).

The images (:func:`reconstruct_images`): for a flow, the minimiser over u with the TV prior, a Chambolle-Pock
primal-dual solve of the convex problem in u,

    K u = (grad u0, grad u1, W_v u1 - u0),   W_v the bilinear warp u1 -> u1(x + v) (a sparse linear map),
    dual steps: p_k <- proj_{|p| <= alpha}(p_k + sigma grad ubar_k);  q <- clip(q + sigma c (W ubar1 - ubar0), +-gamma)
    primal:     u0 <- prox_D(u0 + tau (div p0 + c q)),  u1 <- prox_D(u1 + tau (div p1 - W^T (c q))),
    prox_D(t) = (t + tau m f) / (1 + tau m),

c = 1 where x + v stays in the image, tau = sigma = 0.99 / ||K|| with ||K||^2 <= 9 + the largest column sum of
W. Where a frame has no data (m = 0) its image comes from the other frame along the flow and from the prior:
missing data is reconstructed. numpy only: an output for the API, not a per-frame cost of the node.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InputError
from .models import project_dual_tv
from .operators import div, grad


@dataclass(frozen=True)
class JointParams:
    """The joint model's weights: alpha of R(u) (image TV), gamma of C(u, v) (coupling), and the
    primal-dual iterations of one :func:`reconstruct`."""

    alpha: float
    gamma: float
    iterations: int


@dataclass
class JointState:
    """The images and the dual variables of one level (carried from warp to warp): u (2, H, W), p (2, 2, H, W)
    (dual of grad u_k, [k, dir]), q (H, W) (dual of the coupling)."""

    u: np.ndarray
    p: np.ndarray
    q: np.ndarray

    @classmethod
    def start(cls, f0: np.ndarray, f1: np.ndarray) -> JointState:
        """u = f, duals zero."""
        h, w = f0.shape
        return cls(np.stack([f0, f1]).astype(np.float32), np.zeros((2, 2, h, w), np.float32),
                   np.zeros((h, w), np.float32))


@dataclass(frozen=True)
class WarpOperator:
    """W_v: the bilinear sample u1(x + v(x)) as four taps per pixel: flat indices ``idx`` (4, N) and weights
    ``wts`` (4, N) float32 (taps outside the image carry weight 0), and ``inside`` (H, W) float32 (c(x))."""

    idx: np.ndarray
    wts: np.ndarray
    inside: np.ndarray
    shape: tuple[int, int]

    def apply(self, img: np.ndarray) -> np.ndarray:
        """W img: (H, W) -> (H, W)."""
        return (img.reshape(-1)[self.idx] * self.wts).sum(0).reshape(self.shape)

    def adjoint(self, q: np.ndarray) -> np.ndarray:
        """W^T q: (H, W) -> (H, W) (each tap's weight times q scattered back)."""
        n = self.shape[0] * self.shape[1]
        flat = np.bincount(self.idx.reshape(-1), (self.wts * q.reshape(1, -1)).reshape(-1), minlength=n)
        return flat.reshape(self.shape).astype(np.float32)

    def norm_sq_bound(self) -> float:
        """||W||^2 <= ||W||_1 ||W||_inf = (max column sum) * (max row sum <= 1)."""
        n = self.shape[0] * self.shape[1]
        return float(np.bincount(self.idx.reshape(-1), self.wts.reshape(-1), minlength=n).max(initial=0.0))


def warp_operator(v: np.ndarray) -> WarpOperator:
    """:class:`WarpOperator` of the flow v (2, H, W) px; pixels whose x + v leaves the image get c = 0."""
    h, w = v.shape[1:]
    xs = np.arange(w, dtype=np.float32)[None, :] + v[0]
    ys = np.arange(h, dtype=np.float32)[:, None] + v[1]
    inside = ((xs >= 0) & (xs <= w - 1) & (ys >= 0) & (ys <= h - 1)).astype(np.float32)
    x0, y0 = np.floor(xs), np.floor(ys)
    tx, ty = xs - x0, ys - y0
    xi = np.clip(x0.astype(np.int64), 0, w - 1)
    yi = np.clip(y0.astype(np.int64), 0, h - 1)
    xj, yj = np.minimum(xi + 1, w - 1), np.minimum(yi + 1, h - 1)
    idx = np.stack([yi * w + xi, yi * w + xj, yj * w + xi, yj * w + xj]).reshape(4, -1)
    wts = np.stack([(1 - tx) * (1 - ty), tx * (1 - ty), (1 - tx) * ty, tx * ty]) * inside
    return WarpOperator(idx, wts.reshape(4, -1).astype(np.float32), inside, (h, w))


def coupling(u: np.ndarray, op: WarpOperator) -> np.ndarray:
    """c(x) (u1(x + v) - u0(x)): the argument of C(u, v). -> (H, W)."""
    return op.inside * (op.apply(u[1]) - u[0])


def joint_energy(u: np.ndarray, f: np.ndarray, m: np.ndarray, op: WarpOperator, p: JointParams) -> float:
    """D(u, f) + alpha R(u) + gamma C(u, v) for fixed v (float64 sums): what :func:`reconstruct` decreases."""
    u64 = u.astype(np.float64)
    data = 0.5 * float(np.sum(m * (u64 - f) ** 2))
    g = grad(u64)  # (2 dir, 2 images, H, W)
    tv = float(np.sqrt((g * g).sum(0)).sum())
    return data + p.alpha * tv + p.gamma * float(np.abs(coupling(u64, op)).sum())


def reconstruct(state: JointState, f: np.ndarray, m: np.ndarray, v: np.ndarray, p: JointParams) -> JointState:
    """Minimise the joint energy over u for the flow v (2, H, W) px: f (2, H, W) the level's measured frames,
    m (2, H, W) their data weights (the masks; ones without). Starts from ``state`` and updates it in place
    (``p.iterations`` primal-dual steps, see the module docstring); returns it."""
    op = warp_operator(v)
    step = 0.99 / np.sqrt(9.0 + op.norm_sq_bound())
    tau = sigma = np.float32(step)
    u, pd, q = state.u, state.p, state.q
    u_bar = u.copy()
    for _ in range(p.iterations):
        g = grad(u_bar)  # (dir, k, H, W)
        pt = pd + sigma * np.moveaxis(g, 0, 1)
        pd = np.stack([project_dual_tv(pk, p.alpha, "isotropic") for pk in pt])  # a ball per image k
        q = np.clip(q + sigma * coupling(u_bar, op), -p.gamma, p.gamma)
        cq = op.inside * q
        t0 = u[0] + tau * (div(np.ascontiguousarray(pd[0])) + cq)
        t1 = u[1] + tau * (div(np.ascontiguousarray(pd[1])) - op.adjoint(cq))
        u_new = (np.stack([t0, t1]) + tau * m * f) / (1.0 + tau * m)
        u_bar = 2.0 * u_new - u
        u = u_new.astype(np.float32)
    state.u, state.p, state.q = u, pd.astype(np.float32), q.astype(np.float32)
    return state



def reconstruct_images(f0: np.ndarray, f1: np.ndarray, flow: np.ndarray,
                       mask: tuple[np.ndarray, np.ndarray] | None = None, alpha: float = 0.002, gamma: float = 0.02,
                       iterations: int = 200) -> tuple[np.ndarray, np.ndarray]:
    """The joint model's images for a flow: f0, f1 grey float32 (H, W) in [0, 1] (frames as ``to_grey`` gives
    them), flow (H, W, 2) px from f0 to f1, ``mask`` the frames' validity masks ((H, W) bool each; None: all
    valid); ``alpha`` the images' TV weight, ``gamma`` the coupling's. Returns (u0, u1) float32 (H, W):
    denoised along the motion, and filled in where a frame has no data. InputError for mismatched shapes."""
    if f0.shape != f1.shape or flow.shape != f0.shape + (2,):
        raise InputError(f"reconstruct_images: frames {f0.shape}, {f1.shape} and flow {flow.shape} do not match")
    f = np.stack([f0, f1]).astype(np.float32)
    m = np.ones_like(f) if mask is None else np.stack(mask).astype(np.float32)
    v = np.moveaxis(flow, -1, 0).astype(np.float32)
    state = reconstruct(JointState.start(f[0], f[1]), f, m, v, JointParams(alpha, gamma, iterations))
    return state.u[0], state.u[1]
