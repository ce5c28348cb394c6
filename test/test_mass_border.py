"""The mass model's border term (issue 27, the rotation's border band; off in the engine, see
refine.MASS_AFFINE_BORDER): the regulariser's subgradient at the flow's affine fit (models.affine_border_term)
lives on the border and makes the energy a Bregman distance to the fit; the solver wrapper
(solver.affine_neutral) is the same on both backends and keeps a rotation from the band the plain energy
prefers."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from synth import texture

from flow_node.core import photometric, refine
from flow_node.core.backends import NUMPY
from flow_node.core.config import FlowConfig
from flow_node.core.models import MODEL_SPECS, affine_border_term, affine_fit, tv_norm_of
from flow_node.core.numba_backend import solve_numba
from flow_node.core.operators import grad
from flow_node.core.solver import PDState, Problem, SolveParams, affine_neutral, solve_numpy

H, W = 36, 50
AGREE = 1e-5


def rotation(h: int, w: int, omega: float, shift: tuple[float, float] = (0.3, -0.2)) -> np.ndarray:
    """The flow (2, h, w) px of a rotation by ``omega`` rad about the centre plus a shift."""
    ys, xs = np.mgrid[:h, :w].astype(np.float64)
    xc, yc = xs - (w - 1) / 2.0, ys - (h - 1) / 2.0
    return np.stack([-omega * yc + shift[0], omega * xc + shift[1]]).astype(np.float32)


def test_affine_fit_reproduces_an_affine_flow_and_projects() -> None:
    v = rotation(H, W, 0.01)
    np.testing.assert_allclose(affine_fit(v), v, atol=1e-5)
    noise = np.random.default_rng(0).standard_normal((2, H, W)).astype(np.float32)
    fit = affine_fit(v + noise)
    np.testing.assert_allclose(affine_fit(fit), fit, atol=1e-5)  # a projection
    assert np.abs(fit - v).max() < 0.5


@pytest.mark.parametrize("regulariser", ["tv", "l2"])
@pytest.mark.parametrize("tv_norm", ["isotropic", "anisotropic"])
def test_border_term_lives_on_the_border_and_is_a_bregman_distance(regulariser: str, tv_norm: str) -> None:
    v = rotation(H, W, 0.02)
    b = affine_border_term(v, regulariser, tv_norm)
    assert np.abs(b[:, 1:-1, 1:-1]).max() < 1e-5
    # the border is pulled along it: v (tangential) on the left/right columns, u on the top/bottom rows
    assert min(np.abs(b[1, 1:-1, [0, -1]]).min(), np.abs(b[0, [0, -1], 1:-1]).min()) > 1e-3
    # R(u) - <b, u> >= R(v_aff) - <b, v_aff>: the subgradient inequality at the affine fit, for any u
    spec = MODEL_SPECS["l1_tv" if regulariser == "tv" else "l2_l2"]
    assert spec.regulariser == regulariser

    def shifted(u: np.ndarray) -> float:
        g = grad(u.astype(np.float64))
        reg = tv_norm_of(g, tv_norm) if regulariser == "tv" else 0.5 * float(np.sum(g * g))
        return reg - float(np.sum(b * u))

    base = shifted(v)
    rng = np.random.default_rng(1)
    for k in range(20):
        band = np.zeros((2, H, W), np.float32)
        band[1, :, : 3 + k % 5] = 0.05 * (k + 1)  # a band of changed tangential flow at the left edge
        u = v + band + (0.02 * rng.standard_normal((2, H, W))).astype(np.float32) * (k % 2)
        assert shifted(u) >= base - 1e-4  # float32 b
    # without the term, lowering the ends of the ramp pays: that is the band's reward
    lowered = v.copy()
    lowered[1, :, :4] = v[1, :, 4:5]
    g0, g1 = grad(v.astype(np.float64)), grad(lowered.astype(np.float64))
    plain = (tv_norm_of(g1, tv_norm) - tv_norm_of(g0, tv_norm) if regulariser == "tv"
             else 0.5 * float(np.sum(g1 * g1) - np.sum(g0 * g0)))
    assert plain < 0.0
    assert shifted(lowered) >= base - 1e-4  # neutral: a monotone profile costs its Bregman distance, 0


def test_border_term_of_a_constant_flow_is_zero() -> None:
    v = np.stack([np.full((H, W), 0.7), np.full((H, W), -1.2)]).astype(np.float32)
    assert np.abs(affine_border_term(v, "tv", "isotropic")).max() < 1e-3


def mass_case(seed: int) -> tuple[Problem, PDState]:
    rng = np.random.default_rng(seed)
    f32 = np.float32
    a = (0.2 * rng.standard_normal((2, H, W))).astype(f32)
    m = (0.8 + 0.3 * rng.standard_normal((2, 2, H, W))).astype(f32)
    c = (0.05 * rng.standard_normal((H, W))).astype(f32)
    st = PDState.zeros(MODEL_SPECS["l1_tv"], (H, W))
    st.v = rotation(H, W, 0.03) + (0.1 * rng.standard_normal((2, H, W))).astype(f32)
    st.y = np.clip(0.4 * rng.standard_normal(st.y.shape), -0.7, 0.7).astype(f32)
    st.p = (0.5 * rng.standard_normal((H, W))).astype(f32)
    return Problem(a, c, m=m), st


def test_affine_neutral_is_the_same_on_both_backends_and_passes_other_problems() -> None:
    prob, st0 = mass_case(3)
    params = SolveParams(MODEL_SPECS["l1_tv"], 0.05, 0.3, "isotropic", 40, 0.0)
    ref, fast, plain = copy.deepcopy(st0), copy.deepcopy(st0), copy.deepcopy(st0)
    affine_neutral(solve_numpy)(prob, ref, params)
    affine_neutral(solve_numba)(prob, fast, params)
    solve_numpy(prob, plain, params)
    for name in ("v", "y", "p"):
        assert np.max(np.abs(getattr(ref, name) - getattr(fast, name))) < AGREE, name
    assert np.max(np.abs(ref.v - plain.v)) > 1e-3  # the term acts
    grey, a, b = Problem(prob.a, prob.c), copy.deepcopy(st0), copy.deepcopy(st0)
    affine_neutral(solve_numpy)(grey, a, params)
    solve_numpy(grey, b, params)
    np.testing.assert_array_equal(a.v, b.v)


def test_the_band_is_in_the_plain_energy_and_the_border_term_removes_it() -> None:
    """An exactly rendered density rotated by 0.02 rad (80 x 60), the mass problem linearised around the ground
    truth and solved from it: plain TV takes the flow into a band of too small tangential flow along the
    border (0.17 px in the outer 5 px), with the border term it stays near (0.04 px)."""
    h, w, om = 60, 80, 0.02
    tex = texture(h, w, seed=3, cell=3)
    ys, xs = np.mgrid[:h, :w].astype(np.float64)
    xc, yc = xs - (w - 1) / 2.0, ys - (h - 1) / 2.0
    cos, sin = np.cos(om), np.sin(om)
    i0 = tex.sample(xs, ys).astype(np.float32)
    i1 = tex.sample(cos * xc + sin * yc + (w - 1) / 2.0, -sin * xc + cos * yc + (h - 1) / 2.0).astype(np.float32)
    gt = np.stack([cos * xc - sin * yc - xc, sin * xc + cos * yc - yc]).astype(np.float32)
    cfg = FlowConfig().with_overrides(["constraint=mass"])
    s0, s1 = photometric.preprocess(i0, i1, cfg.photometric)
    problem = refine.problem_source(cfg)(s0, s1, cfg, NUMPY, True)(gt)
    spec = MODEL_SPECS[cfg.model]
    edge = np.minimum(np.minimum(ys, h - 1 - ys), np.minimum(xs, w - 1 - xs)) < 5
    errors = {}
    for name, solve in (("plain", solve_numpy), ("border term", affine_neutral(solve_numpy))):
        st = PDState.zeros(spec, (h, w))
        st.v = gt.copy()
        for _ in range(10):
            solve(problem, st, SolveParams(spec, cfg.alpha, cfg.alpha1, cfg.tv_norm, 100, 0.0))
        errors[name] = float(np.hypot(*(st.v - gt))[edge].mean())
    assert errors["plain"] > 0.1, errors
    assert errors["border term"] < 0.4 * errors["plain"], errors
