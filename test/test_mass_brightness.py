"""The brightness-constancy term beside the mass term (FlowConfig.mass_brightness): its prox in the metric of the
per-pixel steps, numba = numpy for every model, the energy it adds, Bregman, and the linearisation that builds it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from synth import texture
from test_mass import H, W, assert_states_agree, copy_state, random_case

from flow_node.core.api import FlowEstimator
from flow_node.core.backends import NUMPY
from flow_node.core.bregman import bregman
from flow_node.core.config import MODELS, FlowConfig
from flow_node.core.models import (
    MODEL_SPECS,
    energy,
    prox_data_l1,
    prox_data_l2,
    prox_data_metric,
    residual,
)
from flow_node.core.numba_backend import solve_numba
from flow_node.core.operators import gain_linearise, linearise, mass_gain, warp_source
from flow_node.core.refine import MASS_BRIGHTNESS_MIN_SIDE, grey_problem, masked_problem, mass_problem
from flow_node.core.solver import PDState, Problem, SolveParams, solve_numpy
from flow_node.core.validity import data_weight

ITERATIONS = 40


def brightness_case(model: str, data_bregman: bool, seed: int) -> tuple[Problem, PDState]:
    """A random mass problem (test_mass.random_case) with a random brightness term beside it."""
    prob, st = random_case(model, data_bregman, seed)
    rng = np.random.default_rng(1000 + seed)
    ab = (0.3 * rng.standard_normal((2, H, W))).astype(np.float32)
    cb = (0.1 * rng.standard_normal((H, W))).astype(np.float32)
    return dataclasses.replace(prob, ab=ab, cb=cb), st


@pytest.mark.parametrize("data", ["l1", "l2"])
def test_metric_prox_is_the_minimiser(data: str) -> None:
    """prox_data_metric minimises sum_k (v_k - vt_k)^2 / (2 t_k) + lam D(a . v + c) per pixel (no random
    perturbation does better), and with equal steps t it is the paper's prox with tau lam."""
    rng = np.random.default_rng(1)
    vt, a = rng.normal(size=(2, 20, 30)), rng.normal(size=(2, 20, 30))
    c, t, lam = rng.normal(size=(20, 30)), rng.uniform(0.05, 0.5, (2, 20, 30)), 3.0
    out = prox_data_metric(vt, a, c, t, lam, data)

    def objective(v: np.ndarray) -> np.ndarray:
        r = residual(v, a, c)
        d = np.abs(r) if data == "l1" else 0.5 * r * r
        return np.sum((v - vt) ** 2 / (2 * t), axis=0) + lam * d

    best = objective(out)
    for _ in range(50):
        assert np.all(objective(out + 1e-3 * rng.normal(size=out.shape)) >= best - 1e-12)
    paper = prox_data_l1 if data == "l1" else prox_data_l2
    np.testing.assert_allclose(prox_data_metric(vt, a, c, np.full_like(t, 0.25), lam, data),
                               paper(vt, a, c, 0.25 * lam), atol=1e-12)


@pytest.mark.parametrize("bregman_term", [False, True], ids=["plain", "bregman"])
@pytest.mark.parametrize("tv_norm", ["isotropic", "anisotropic"])
@pytest.mark.parametrize("model", MODELS)
def test_numba_matches_numpy_with_the_brightness_term(model: str, tv_norm: str, bregman_term: bool) -> None:
    prob, st0 = brightness_case(model, bregman_term, seed=10 + MODELS.index(model))
    alpha = 0.002 if model.startswith("l2") else 0.05
    params = SolveParams(MODEL_SPECS[model], alpha, 0.3, tv_norm, ITERATIONS, 0.0)
    ref, fast = copy_state(st0), copy_state(st0)
    assert solve_numpy(prob, ref, params) == ITERATIONS
    assert solve_numba(prob, fast, params) == ITERATIONS
    without = copy_state(st0)  # the same problem without the term: the term must change the result
    solve_numpy(dataclasses.replace(prob, ab=None, cb=None), without, params)
    assert np.max(np.abs(ref.v - without.v)) > 1e-3
    assert_states_agree(ref, fast)


@pytest.mark.parametrize("model", MODELS)
def test_solve_lowers_the_energy_with_the_brightness_term(model: str) -> None:
    prob, _ = brightness_case(model, False, seed=7)
    spec = MODEL_SPECS[model]
    alpha = 0.002 if model.startswith("l2") else 0.05
    params = SolveParams(spec, alpha, 0.3, "isotropic", 300, 0.0)
    st = PDState.zeros(spec, (H, W))

    def e() -> float:
        return energy(spec, st.v, st.w, prob.a, prob.c, alpha, 0.3, "isotropic", m=prob.m, bc=(prob.ab, prob.cb))

    e0 = e()
    solve_numpy(prob, st, params)
    assert e() < 0.5 * e0
    # the term is in the energy: its data penalty on ab . v + cb added to the mass energy
    rb = residual(st.v.astype(np.float64), prob.ab, prob.cb)
    extra = 0.5 * np.sum(rb * rb) if spec.data == "l2" else np.abs(rb).sum()
    assert e() == pytest.approx(energy(spec, st.v, st.w, prob.a, prob.c, alpha, 0.3, "isotropic", m=prob.m) + extra)


def test_bregman_shifts_the_brightness_term_by_its_own_residual() -> None:
    prob, st = brightness_case("l2_tv", False, seed=3)
    seen: list[Problem] = []

    def solve(step: Problem, state: PDState, p: SolveParams) -> int:
        seen.append(step)
        return 1

    p = SolveParams(MODEL_SPECS["l2_tv"], 0.05, 0.0, "isotropic", 10, 0.0)
    assert bregman(prob, st, p, solve, 2) == 2
    assert all(s.m is prob.m and s.ab is prob.ab for s in seen)
    np.testing.assert_allclose(seen[0].cb, prob.cb + residual(st.v, prob.ab, prob.cb), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(seen[1].cb, prob.cb + 2 * residual(st.v, prob.ab, prob.cb), rtol=1e-5, atol=1e-6)


def test_the_default_beta() -> None:
    """0.1 for every model (chosen on the tune split, docs/engine.md); a given value wins."""
    for model in MODELS:
        assert FlowConfig().replace(constraint="mass", model=model).mass_brightness == 0.1
    assert FlowConfig().replace(model="l2_tv", mass_brightness=0.3).mass_brightness == 0.3


def test_gain_linearisation_is_that_of_the_rescaled_frame() -> None:
    """gain_linearise(.., g) is the linearisation of g I1 against I0 (so a global density gain is no residual)."""
    i0 = texture(H, W, seed=1).image.astype(np.float32)
    i1 = (texture(H, W, seed=2).image / 1.15).astype(np.float32)
    v0 = (0.8 * np.random.default_rng(4).normal(size=(2, H, W))).astype(np.float32)
    g = mass_gain(i0, i1)
    assert g == pytest.approx(float(i0.sum() / i1.sum()))
    a, c = linearise(i0, warp_source(i1, "central", "bspline"), None, v0, "central")
    ga, gc = linearise(i0, warp_source(g * i1, "central", "bspline"), None, v0, "central")
    out_a, out_c = gain_linearise(i0, a, c, v0, g)
    np.testing.assert_allclose(out_a, ga, atol=1e-5)
    np.testing.assert_allclose(out_c, gc, atol=1e-5)
    # a pure gain: frame 1 = frame 0 / 1.15 at zero flow leaves no residual after the gain
    zero = np.zeros((2, H, W), np.float32)
    a, c = linearise(i0, warp_source(i0 / 1.15, "central", "bspline"), None, zero, "central")
    assert np.max(np.abs(c)) > 0.01
    np.testing.assert_allclose(gain_linearise(i0, a, c, zero, mass_gain(i0, i0 / 1.15))[1], 0.0, atol=1e-5)


@pytest.mark.parametrize("model", ["l1_tv", "l2_tv"])
def test_mass_problem_carries_the_weighted_grey_linearisation(model: str) -> None:
    """beta > 0: the mass problem keeps the grey-value linearisation (of the frames at equal mass) beside it, its
    weight folded in (beta for L1, sqrt(beta) for L2, so the data penalty is beta D(rho)); beta = 0 none."""
    h, w = MASS_BRIGHTNESS_MIN_SIDE, MASS_BRIGHTNESS_MIN_SIDE + 14
    i0 = texture(h, w, seed=1).image.astype(np.float32)
    i1 = texture(h, w, seed=2).image.astype(np.float32)
    v0 = (0.3 * np.random.default_rng(4).normal(size=(2, h, w))).astype(np.float32)
    cfg = FlowConfig().replace(constraint="mass", model=model, mass_brightness=0.0)
    assert mass_problem(i0, i1, cfg, NUMPY, False)(v0).ab is None
    small = (slice(None), slice(1, None), slice(None))  # one row fewer than the smallest level with the term
    assert mass_problem(i0[1:], i1[1:], cfg.replace(mass_brightness=0.4), NUMPY, False)(v0[small]).ab is None
    beta = 0.4
    with_term = mass_problem(i0, i1, cfg.replace(mass_brightness=beta), NUMPY, False)(v0)
    plain = mass_problem(i0, i1, cfg, NUMPY, False)(v0)
    np.testing.assert_array_equal(with_term.m, plain.m)
    grey = grey_problem(i0, i1, cfg, NUMPY, False)(v0)
    ga, gc = gain_linearise(i0, grey.a, grey.c, v0, mass_gain(i0, i1))
    weight = beta if model == "l1_tv" else np.sqrt(beta)
    assert np.max(np.abs(ga)) > 1e-3
    np.testing.assert_allclose(with_term.ab, weight * ga, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(with_term.cb, weight * gc, rtol=1e-6, atol=1e-7)


def test_brightness_term_holds_the_rotations_border_band() -> None:
    """fine_320's first report rotation (div v = 0, 8 bit): the pure continuity equation leaves a band of too small
    tangential flow at the border (docs/engine.md, "The border band"); with the default brightness term the mass
    model's AEE drops below half of it and within 1.1x brightness constancy's (measured 0.025 -> 0.008; 0.012)."""
    from bench.suite import synthetic
    from bench.suite.metrics import band_aee
    from flow_node.bag.scenes import render_grey_pair

    scene, label = synthetic.scene_for(1, synthetic.REPORT_SEED0 + 1, (320, 240))
    assert label.startswith("rotation")
    i0, i1, gt = render_grey_pair(scene)
    q0, q1 = synthetic.quantise(i0, 8), synthetic.quantise(i1, 8)
    base = FlowConfig(backend="numba")
    errors, bands = {}, {}
    for name, cfg in (("brightness", base), ("pure", base.replace(constraint="mass", mass_brightness=0.0)),
                      ("beta", base.replace(constraint="mass"))):
        flow = FlowEstimator(cfg).estimate(q0, q1).flow
        err = np.hypot(flow[..., 0] - gt[..., 0], flow[..., 1] - gt[..., 1])
        errors[name], bands[name] = float(err.mean()), band_aee(err)
    assert errors["beta"] <= 0.5 * errors["pure"], errors
    assert errors["beta"] <= 1.1 * errors["brightness"], errors
    assert bands["beta"]["0-2"] <= 0.6 * bands["pure"]["0-2"], bands


@pytest.mark.parametrize("model", ["l1_tv", "l2_tv"])
def test_validity_mask_weights_the_whole_mass_problem(model: str) -> None:
    """A validity mask weights every coefficient of the mass residual a . v + M : grad v + c and of the
    brightness term beside it (refine.masked_problem): masked pixels keep no data term at all, valid ones keep
    the unmasked problem. (Until 2026-12-05 the mask dropped M and the brightness term: a masked mass problem
    was a brightness problem on the mass linearisation's a and c.)"""
    h, w = MASS_BRIGHTNESS_MIN_SIDE, MASS_BRIGHTNESS_MIN_SIDE + 14
    i0 = texture(h, w, seed=1).image.astype(np.float32)
    i1 = texture(h, w, seed=2).image.astype(np.float32)
    v0 = (0.3 * np.random.default_rng(4).normal(size=(2, h, w))).astype(np.float32)
    cfg = FlowConfig().replace(constraint="mass", model=model, mass_brightness=0.4)
    plain = mass_problem(i0, i1, cfg, NUMPY, False)(v0)
    valid = np.ones((h, w), np.float32)
    valid[20:30, 25:40] = 0.0
    masked = masked_problem(mass_problem(i0, i1, cfg, NUMPY, False), valid, np.ones_like(valid),
                            MODEL_SPECS[model].data)(v0)
    weight = data_weight(valid, np.ones_like(valid), v0)
    inside, outside = weight == 0.0, weight == 1.0
    assert inside.any() and outside.any()
    for name in ("a", "c", "m", "ab", "cb"):
        got, ref = getattr(masked, name), getattr(plain, name)
        assert got is not None and got.shape == ref.shape, name
        np.testing.assert_array_equal(got[..., outside], ref[..., outside], err_msg=name)
        assert np.all(got[..., inside] == 0.0), name
