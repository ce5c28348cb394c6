"""Discrete operators of the paper ("Discretization and Parameters"), numpy reference versions.

Arrays are channel-first: a scalar field is (H, W), a vector field (2, H, W) with index 0 = x (columns,
rightwards) and 1 = y (rows, downwards); on a volume (Z, Y, X) and (3, Z, Y, X) with index 2 = z (slices).
``grad`` is the forward difference with Neumann boundary (zero in the last column/row/slice) and ``div``
the backward difference chosen so that ``<grad f, p> = -<f, div p>`` holds exactly: these are the blocks
of the paper's K and K*.

Image derivatives (the paper's Table 2 schemes) are separate from ``grad``: they feed the data term only.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .warping import NUMPY_WARPER, Warper


def _axis(k: int, ndim: int, sl: slice) -> tuple[slice, ...]:
    """Index of ``sl`` along spatial direction k of an array with ``ndim`` axes (direction 0 = the last axis,
    x; 1 = the one before, y; 2 = z), all other axes whole."""
    index = [slice(None)] * ndim
    index[ndim - 1 - k] = sl
    return tuple(index)


_HEAD, _TAIL, _LAST = slice(None, -1), slice(1, None), slice(-1, None)


def grad(f: np.ndarray, out: np.ndarray | None = None, dims: int = 2) -> np.ndarray:
    """Forward-difference gradient with Neumann boundary over the last ``dims`` axes (2: an image, 3: a
    volume). f: (..., [Z,] Y, X) -> (dims, ..., [Z,] Y, X), direction k along axis -(k+1): 0 = x, 1 = y,
    2 = z. Zero in the last entry of each direction."""
    if out is None:
        out = np.zeros((dims,) + f.shape, dtype=f.dtype)
    for k in range(dims):
        np.subtract(f[_axis(k, f.ndim, _TAIL)], f[_axis(k, f.ndim, _HEAD)], out=out[k][_axis(k, f.ndim, _HEAD)])
        out[k][_axis(k, f.ndim, _LAST)] = 0.0
    return out


def div(p: np.ndarray) -> np.ndarray:
    """Backward-difference divergence, the negative adjoint of :func:`grad`; the number of spatial axes is
    p.shape[0]. p: (dims, ..., [Z,] Y, X) -> (..., [Z,] Y, X)."""
    d = np.zeros(p.shape[1:], dtype=p.dtype)
    for k in range(p.shape[0]):
        # div_k p[j] = p[j] (j < N-1) - p[j-1] (j > 0); the last entry of p is never produced by grad
        head = p[k][_axis(k, d.ndim, _HEAD)]
        d[_axis(k, d.ndim, _HEAD)] += head
        d[_axis(k, d.ndim, _TAIL)] -= head
    return d


def jacobian_central(v: np.ndarray) -> np.ndarray:
    """Central-difference Jacobian of a flow: J[k, l] = d v_k / d x_l = (v_k(x + e_l) - v_k(x - e_l)) / 2,
    zero on the border columns (l = 0) / rows (l = 1) as the central image gradient: the derivative at the
    pixel itself. v (2, H, W) -> (2, 2, H, W) [component, direction]."""
    j = np.zeros((2,) + v.shape, dtype=v.dtype)
    j[:, 0, :, 1:-1] = 0.5 * (v[:, :, 2:] - v[:, :, :-2])
    j[:, 1, 1:-1, :] = 0.5 * (v[:, 2:, :] - v[:, :-2, :])
    return j


def jacobian_central_adjoint(q: np.ndarray) -> np.ndarray:
    """The adjoint of :func:`jacobian_central`: q (2, 2, H, W) -> (2, H, W), component k at x =
    sum_l (q[k, l](x - e_l) - q[k, l](x + e_l)) / 2, q read as zero on its border columns/rows and outside."""
    out = np.zeros((2,) + q.shape[2:], dtype=q.dtype)
    qx = np.zeros_like(q[:, 0])
    qx[:, :, 1:-1] = q[:, 0, :, 1:-1]
    out[:, :, 1:] += 0.5 * qx[:, :, :-1]
    out[:, :, :-1] -= 0.5 * qx[:, :, 1:]
    qy = np.zeros_like(q[:, 1])
    qy[:, 1:-1, :] = q[:, 1, 1:-1, :]
    out[:, 1:, :] += 0.5 * qy[:, :-1, :]
    out[:, :-1, :] -= 0.5 * qy[:, 1:, :]
    return out


def image_gradient(img: np.ndarray, scheme: str, out: np.ndarray | None = None) -> np.ndarray:
    """Spatial derivative of an image or volume for the data term. img: (H, W) or (Z, Y, X) -> (img.ndim,
    *img.shape) float32 in direction order x, y[, z], intensity per pixel.

    ``forward``: I(x+1) - I(x), zero in the last entry of each direction. ``central`` (and ``interpolated``,
    which applies it to a temporally interpolated image): (I(x+1) - I(x-1)) / 2, zero on the border as in the
    paper. Note the paper writes the central difference without the 1/2; we keep the true derivative so
    that flow is in pixels, and the paper's weights map onto ours by alpha_ours = alpha_paper / 2.
    ``out``: a float32 array of the result's shape to write into (returned), else a new one; it must not
    overlap img (a later component would read what an earlier one wrote).
    """
    if out is not None and np.may_share_memory(img, out):
        raise ValueError("image_gradient: out overlaps the image")
    n = img.ndim
    g = np.empty((n,) + img.shape, dtype=np.float32) if out is None else out
    for k in range(n):
        if scheme == "forward":
            np.subtract(img[_axis(k, n, _TAIL)], img[_axis(k, n, _HEAD)], out=g[k][_axis(k, n, _HEAD)])
            g[k][_axis(k, n, _LAST)] = 0.0
        else:
            inner = _axis(k, n, slice(1, -1))
            np.subtract(img[_axis(k, n, slice(2, None))], img[_axis(k, n, slice(None, -2))], out=g[k][inner])
            g[k][inner] *= 0.5
            g[k][_axis(k, n, slice(0, 1))] = 0.0
            g[k][_axis(k, n, _LAST)] = 0.0
    return g


def warp_maps(flow: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sampling maps x + u, y + v for the warp (warping.py) and the mask of points that stay inside the image.

    flow: (2, H, W) px. Returns map_x, map_y (H, W) float32 and inside (H, W) bool.
    """
    h, w = flow.shape[1:]
    xs = np.arange(w, dtype=np.float32)[None, :]
    ys = np.arange(h, dtype=np.float32)[:, None]
    map_x = (xs + flow[0]).astype(np.float32)
    map_y = (ys + flow[1]).astype(np.float32)
    inside = (map_x >= 0) & (map_x <= w - 1) & (map_y >= 0) & (map_y <= h - 1)
    return map_x, map_y, inside


# image_gradient(img, scheme, out) -> gradient: :func:`image_gradient` or a backend's kernel (the same values)
ImageGradient = Callable[..., np.ndarray]


def warp_source(i1: np.ndarray, scheme: str, kernel: str, warper: Warper = NUMPY_WARPER,
                out: np.ndarray | None = None, gradient: ImageGradient = image_gradient) -> np.ndarray:
    """What each warp of one level samples: (3, H, W) float32 = [I1, its image gradient (scheme)] as the
    kernel's coefficients. Built once per level. For the B-spline only I1 is prefiltered and the gradient
    taken of its coefficients: both filters are linear and shift-invariant, so that is the prefiltered
    gradient (away from the one-pixel border) at a third of the prefilter's cost. ``out``: a float32
    (3, H, W) array to write into (returned), else a new one. ``gradient``: :func:`image_gradient` or a
    backend's."""
    src = np.empty((3,) + np.shape(i1), dtype=np.float32) if out is None else out
    src[0] = warper.coefficients(i1, kernel)
    gradient(src[0], scheme, out=src[1:])
    return src


# linearise(i0, source1, grad_i0, flow0, scheme, kernel, warper) -> (a, c): :func:`linearise` or a backend's
Linearise = Callable[..., tuple[np.ndarray, np.ndarray]]


def linearise(i0: np.ndarray, source1: np.ndarray, grad_i0: np.ndarray | None, flow0: np.ndarray, scheme: str,
              kernel: str = "bspline", warper: Warper = NUMPY_WARPER) -> tuple[np.ndarray, np.ndarray]:
    """Linearised brightness constancy around flow0 (paper, "Large Displacements").

    rho(v) = I1(x + v0) + grad I1(x + v0) . (v - v0) - I0(x) = a . v + c, with a the image gradient of the
    chosen scheme. I1 and its gradient (``source1``, :func:`warp_source`) are sampled at x + v0 with one
    cubic ``kernel`` (warping.py), so the warped gradient is that of the same interpolant family. Returns
    a (2, H, W) and c (H, W); both are zero where x + v0 leaves the image, which removes those pixels from
    the data term. Without warping (v0 = 0) c is the paper's u_t = I1 - I0.
    """
    map_x, map_y, inside = warp_maps(flow0)
    warped = warper.sample(source1, map_x, map_y, kernel)
    i1w, a = warped[0], warped[1:]
    if scheme == "interpolated":
        a = 0.5 * (grad_i0 + a)
    c = i1w - i0 - a[0] * flow0[0] - a[1] * flow0[1]
    a *= inside
    c *= inside
    return a.astype(np.float32, copy=False), c.astype(np.float32, copy=False)


def mass_gain(i0: np.ndarray, i1: np.ndarray) -> float:
    """g = sum I0 / sum I1: the gain that gives frame 1 frame 0's mass (1 for a flow that moves no mass across
    the border; det M for an affine map x -> M x + b of a density inside the image). i0, i1 (H, W)."""
    return float(np.sum(i0, dtype=np.float64) / max(float(np.sum(i1, dtype=np.float64)), 1e-12))


def gain_linearise(i0: np.ndarray, a: np.ndarray, c: np.ndarray, flow0: np.ndarray, gain: float
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Brightness constancy of the frames brought to equal mass, g I1(x + v) = I0(x), linearised about flow0 from
    the plain linearisation (a, c) around it (c = I1w - I0 - a . v0): rho(v) = g a . v + g c + (g - 1) I0, zero
    where x + v0 leaves the image. The brightness term beside the mass term (refine.mass_problem): a global
    density gain (an affine map's constant det) is then no brightness change, so the term does not read it as
    motion. -> (2, H, W), (H, W) float32."""
    inside = warp_maps(flow0)[2]
    g = np.float32(gain)
    return (g * a).astype(np.float32), (g * c + (g - np.float32(1.0)) * i0 * inside).astype(np.float32)


def mass_linearise(i0: np.ndarray, a: np.ndarray, c: np.ndarray, flow0: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mass preservation I1(x + v) det(Id + grad v) = I0(x) linearised about flow0, from the brightness
    linearisation (a, c) around it (c = I1w - I0 - a . v0, I1w = I1(x + v0), whichever scheme gave a):

        rho(v) = det(J0) a . v + I1w cof(J0) : grad v + c',   J0 = Id + grad v0 (central differences),
        c' = I1w det(J0) - I0 - det(J0) a . v0 - I1w cof(J0) : grad v0,

    first order in v - v0 (det(J) ~ det(J0) + cof(J0) : (J - J0)); with v0 = 0 it is I_t + grad I1 . v +
    I1 div v. Returns a' (2, H, W), M = I1w cof(J0) (2, 2, H, W) [component, direction] and c' (H, W),
    float32, zero where x + v0 leaves the image."""
    inside = warp_maps(flow0)[2]
    i1w = c + i0 + a[0] * flow0[0] + a[1] * flow0[1]
    jac = jacobian_central(flow0.astype(np.float32))
    ux, uy, vx, vy = jac[0, 0], jac[0, 1], jac[1, 0], jac[1, 1]
    det0 = (1.0 + ux) * (1.0 + vy) - uy * vx
    cof = np.stack([np.stack([1.0 + vy, -vx]), np.stack([-uy, 1.0 + ux])])  # d det / d J[k, l]
    a_m = (det0 * a * inside).astype(np.float32)
    m = (i1w * cof * inside).astype(np.float32)
    c_m = (i1w * det0 - i0) * inside - a_m[0] * flow0[0] - a_m[1] * flow0[1] - np.sum(m * jac, axis=(0, 1))
    return a_m, m, c_m.astype(np.float32)
