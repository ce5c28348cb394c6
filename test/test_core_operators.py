"""The discrete operators and prox maps of the paper: adjointness and optimality against brute force."""

import numpy as np
import pytest

from flow_node.core.models import (
    MODEL_SPECS,
    apply_k,
    apply_k_adjoint,
    project_dual_tv,
    prox_data_l1,
    prox_data_l2,
    prox_dual_l2,
    residual,
)
from flow_node.core.numba_backend import image_gradient_numba
from flow_node.core.operators import div, grad, image_gradient, warp_source

RNG = np.random.default_rng(1234)


def test_grad_is_forward_difference_with_neumann_boundary() -> None:
    f = np.arange(12, dtype=np.float64).reshape(3, 4) ** 2
    g = grad(f)
    assert g[0, 1, 1] == f[1, 2] - f[1, 1]
    assert g[1, 1, 1] == f[2, 1] - f[1, 1]
    assert np.all(g[0, :, -1] == 0) and np.all(g[1, -1, :] == 0)


@pytest.mark.parametrize("shape", [(7, 9), (1, 5), (5, 1), (2, 3, 6, 8)])
def test_div_is_negative_adjoint_of_grad(shape: tuple[int, ...]) -> None:
    x = RNG.standard_normal(shape)
    y = RNG.standard_normal((2,) + shape)
    lhs = np.sum(grad(x) * y)
    rhs = -np.sum(x * div(y))
    assert lhs == pytest.approx(rhs, rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("model", list(MODEL_SPECS))
def test_k_adjoint_matches_k(model: str) -> None:
    spec = MODEL_SPECS[model]
    h, w = 6, 8
    v = RNG.standard_normal((2, h, w))
    wf = RNG.standard_normal((2, 2, h, w)) if spec.extended else None
    y = RNG.standard_normal((2, 2, h, w))
    z = RNG.standard_normal((2, 2, 2, h, w)) if spec.regulariser == "tv_tv" else None
    k1, k2 = apply_k(spec, v, wf)
    kv, kw = apply_k_adjoint(spec, y, z)
    lhs = np.sum(k1 * y) + (0.0 if k2 is None else np.sum(k2 * z))
    rhs = np.sum(v * kv) + (0.0 if kw is None else np.sum(wf * kw))
    assert lhs == pytest.approx(rhs, rel=1e-12)


def test_image_gradient_schemes_on_a_ramp() -> None:
    img = np.tile(np.arange(10, dtype=np.float32) * 0.1, (6, 1))  # d/dx = 0.1, d/dy = 0
    fwd = image_gradient(img, "forward")
    cen = image_gradient(img, "central")
    assert fwd[0, 2, :-1] == pytest.approx(0.1) and fwd[0, 2, -1] == 0
    assert cen[0, 2, 1:-1] == pytest.approx(0.1) and cen[0, 2, 0] == 0 and cen[0, 2, -1] == 0
    assert np.all(cen[1] == 0)


GRADIENTS = {"numpy": image_gradient, "numba": image_gradient_numba}


@pytest.mark.parametrize("gradient", GRADIENTS)
@pytest.mark.parametrize("scheme", ["forward", "central", "interpolated"])
@pytest.mark.parametrize("shape", [(6, 9), (1, 5), (5, 1), (2, 2)])
def test_gradient_and_warp_source_write_into_a_given_array(scheme: str, shape: tuple[int, int], gradient: str) -> None:
    """``out`` (the engine's reused scratch, full of stale values) gives exactly the freshly allocated result,
    borders included: every element is written (the numpy reference and the numba backend's kernel)."""
    of = GRADIENTS[gradient]
    img = RNG.random(shape).astype(np.float32)
    stale = np.full((3,) + shape, np.nan, np.float32)
    fresh = of(img, scheme)
    of(img, scheme, out=stale[1:])
    assert np.array_equal(stale[1:], fresh)
    if scheme != "forward":  # zero border, the paper's central difference
        assert np.all(fresh[0][:, [0, -1]] == 0) and np.all(fresh[1][[0, -1]] == 0)
    stale[:] = np.nan
    src = warp_source(img, scheme, "bspline", out=stale, gradient=of)
    assert src is stale and np.array_equal(src, warp_source(img, scheme, "bspline"))


@pytest.mark.parametrize("gradient", GRADIENTS)
def test_gradient_refuses_an_out_that_overlaps_the_image(gradient: str) -> None:
    """In place would be wrong (the y-difference would read x-differences), so it is refused; the warp
    source's gradient of its own first plane into the other two is not an overlap."""
    of = GRADIENTS[gradient]
    buf = RNG.random((3, 6, 9)).astype(np.float32)
    with pytest.raises(ValueError, match="overlaps"):
        of(buf[1], "central", out=buf[1:])
    fresh = image_gradient(buf[0], "central")
    assert np.array_equal(of(buf[0], "central", out=buf[1:]), fresh)


@pytest.mark.parametrize("scheme", ["forward", "central", "interpolated"])
@pytest.mark.parametrize("shape", [(1, 1), (3, 2), (61, 80), (120, 160), (4, 5, 6)])
def test_numba_gradient_is_the_reference_bit_for_bit(scheme: str, shape: tuple[int, ...]) -> None:
    """The numba backend's image gradient (one kernel) gives the numpy reference's values bit for bit on images
    of any size, also on float64 and non-contiguous input and on volumes (which it hands to the reference)."""
    img = (RNG.random(shape) * 3 - 1).astype(np.float32)
    want = image_gradient(img, scheme)
    got = image_gradient_numba(img, scheme)
    assert got.dtype == np.float32 and np.array_equal(got.view(np.int32), want.view(np.int32))
    if len(shape) == 2 and min(shape) > 1:
        view = img[:, ::-1]  # not contiguous: the reference's result
        assert np.array_equal(image_gradient_numba(view, scheme), image_gradient(view, scheme))
        wide = img.astype(np.float64)
        assert np.array_equal(image_gradient_numba(wide, scheme), image_gradient(wide, scheme))


def _brute_force_2d(objective, centre: np.ndarray, radius: float, n: int = 401) -> np.ndarray:
    """Minimise objective(v) for v in R^2 by two rounds of grid search around centre."""
    best = centre
    for r in (radius, radius * 4 / n):
        t = np.linspace(-r, r, n)
        gx, gy = np.meshgrid(best[0] + t, best[1] + t, indexing="ij")
        vals = objective(np.stack([gx, gy]))
        i = np.unravel_index(np.argmin(vals), vals.shape)
        best = np.array([gx[i], gy[i]])
    return best


@pytest.mark.parametrize("case", range(6))
@pytest.mark.parametrize("data", ["l1", "l2"])
def test_data_prox_matches_brute_force(case: int, data: str) -> None:
    rng = np.random.default_rng(case)
    vt = rng.standard_normal(2)
    a = rng.standard_normal(2) * [0.3, 2.0][case % 2]
    c = rng.standard_normal() * 0.5
    tau = [0.05, 0.25, 1.0][case % 3]
    pen = (lambda r: tau * np.abs(r)) if data == "l1" else (lambda r: 0.5 * tau * r * r)

    def objective(v: np.ndarray) -> np.ndarray:
        r = a[0] * v[0] + a[1] * v[1] + c
        return 0.5 * ((v[0] - vt[0]) ** 2 + (v[1] - vt[1]) ** 2) + pen(r)

    prox = prox_data_l1 if data == "l1" else prox_data_l2
    got = prox(vt.reshape(2, 1, 1), a.reshape(2, 1, 1), np.array([[c]]), tau)[:, 0, 0]
    want = _brute_force_2d(objective, vt, 3.0)
    assert objective(got.reshape(2, 1)) <= objective(want.reshape(2, 1)) + 1e-9
    assert np.allclose(got, want, atol=5e-3)


def test_l1_prox_three_cases_and_flat_image() -> None:
    a = np.array([1.0, 0.0]).reshape(2, 1, 1)
    vt = np.zeros((2, 1, 1))
    tau = 0.5
    # rho = c: large negative -> step +tau a; large positive -> -tau a; small -> onto rho = 0
    assert prox_data_l1(vt, a, np.array([[-2.0]]), tau)[0, 0, 0] == pytest.approx(0.5)
    assert prox_data_l1(vt, a, np.array([[2.0]]), tau)[0, 0, 0] == pytest.approx(-0.5)
    got = prox_data_l1(vt, a, np.array([[0.2]]), tau)
    assert residual(got, a, np.array([[0.2]]))[0, 0] == pytest.approx(0.0, abs=1e-12)
    flat = prox_data_l1(np.ones((2, 1, 1)), np.zeros((2, 1, 1)), np.array([[0.3]]), tau)
    assert np.all(flat == 1.0)


@pytest.mark.parametrize("tv_norm", ["isotropic", "anisotropic"])
def test_dual_tv_projection_is_the_nearest_point_of_the_ball(tv_norm: str) -> None:
    alpha = 0.7
    yt = RNG.standard_normal((2, 2, 5, 5)) * 1.5
    p = project_dual_tv(yt, alpha, tv_norm)
    if tv_norm == "isotropic":
        assert np.all(np.sqrt((p**2).sum(axis=(0, 1))) <= alpha + 1e-12)
    else:
        assert np.all(np.abs(p) <= alpha + 1e-12)
    # variational inequality <yt - p, q - p> <= 0 for points q of the ball (brute-force sampling)
    for _ in range(200):
        q = RNG.standard_normal(yt.shape)
        q = project_dual_tv(q, alpha, tv_norm)  # any point of the ball
        assert np.all(((yt - p) * (q - p)).sum(axis=(0, 1)) <= 1e-10)
    inside = yt * 0.01
    assert np.allclose(project_dual_tv(inside, alpha, tv_norm), inside)


def test_dual_l2_prox_matches_closed_form_minimiser() -> None:
    yt, sigma, alpha = RNG.standard_normal((2, 2, 3, 3)), 0.5, 0.2
    got = prox_dual_l2(yt, sigma, alpha)
    # minimiser of |y - yt|^2/2 + sigma |y|^2 / (2 alpha): gradient zero
    assert np.allclose((got - yt) + sigma * got / alpha, 0.0)
