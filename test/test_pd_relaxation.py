"""The over-relaxed primal-dual iteration (SolveParams.relaxation, FlowConfig.pd_relaxation / stream_relaxation).

numba against the numpy reference with rho != 1 for every data-term variant the kernels are compiled for (plain,
quadratic, mass, mass with the brightness term), every model and both TV norms, and with the edge weight; rho = 1
is the plain iteration bit for bit; the relaxed iteration reaches the plain one's minimiser (a wrong relaxation
converges elsewhere or not at all); the config fields reach the solver.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_mass import copy_state
from test_mass import random_case as mass_case
from test_mass_brightness import brightness_case
from test_numba_backend import random_case

from flow_node.core.config import MODELS, FlowConfig
from flow_node.core.models import MODEL_SPECS
from flow_node.core.numba_backend import solve_numba
from flow_node.core.refine import level_params
from flow_node.core.solver import PDState, Problem, SolveParams, solve_numpy
from flow_node.core.temporal import stream_schedule

ITERATIONS = 40
AGREE = 1e-5
RHO = 1.7


def params(model: str, tv_norm: str = "isotropic", rho: float = RHO, iterations: int = ITERATIONS,
           tolerance: float = 0.0) -> SolveParams:
    alpha = 0.002 if model.startswith("l2") else 0.05  # data terms of comparable pull on v (test_numba_backend)
    return SolveParams(MODEL_SPECS[model], alpha, 0.3, tv_norm, iterations, tolerance, relaxation=rho)


def quadratic_case(model: str, seed: int) -> tuple[Problem, PDState]:
    """A random positive semi-definite quadratic data term q (5, H, W) (the census term's form) and a random
    start; weaker for the L2 models, whose alpha in :func:`params` is 25x smaller (else the data term alone
    fixes v within a few steps; l2_l2's strongly convex problem converges within ~40 then)."""
    prob, st = random_case(model, False, seed)
    rng = np.random.default_rng(seed)
    h, w = st.v.shape[1:]
    scale = 0.002 if model.startswith("l2") else 1.0
    j = 0.3 * rng.standard_normal((3, 2, h, w))  # T = scale (sum_k j_k j_k^T + 0.1 I), g = -T v*: minimiser v*
    t = scale * (np.einsum("kahw,kbhw->abhw", j, j) + 0.1 * np.eye(2)[:, :, None, None])
    target = rng.standard_normal((2, h, w))
    g = -np.einsum("abhw,bhw->ahw", t, target)
    q = np.stack([t[0, 0], t[0, 1], t[1, 1], g[0], g[1]]).astype(np.float32)
    return Problem(prob.a, prob.c, q=q), st


def weighted_case(model: str, seed: int) -> tuple[Problem, PDState]:
    """random_case with an edge weight g (H, W) in [0.3, 1] (the radius of y's ball)."""
    prob, st = random_case(model, True, seed)
    g = np.random.default_rng(seed).uniform(0.3, 1.0, st.v.shape[1:]).astype(np.float32)
    return dataclasses.replace(prob, g=g), st


CASES = {"plain": lambda m, s: random_case(m, True, s), "quad": quadratic_case,
         "mass": lambda m, s: mass_case(m, True, s), "bc": lambda m, s: brightness_case(m, False, s),
         "weight": weighted_case}


def fields(st: PDState) -> dict[str, np.ndarray]:
    return {f.name: getattr(st, f.name) for f in dataclasses.fields(st) if getattr(st, f.name) is not None}


@pytest.mark.parametrize("tv_norm", ["isotropic", "anisotropic"])
@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("case", list(CASES))
def test_numba_matches_numpy_relaxed(case: str, model: str, tv_norm: str) -> None:
    prob, st0 = CASES[case](model, MODELS.index(model))
    ref, fast, plain = copy_state(st0), copy_state(st0), copy_state(st0)
    assert solve_numpy(prob, ref, params(model, tv_norm)) == ITERATIONS
    assert solve_numba(prob, fast, params(model, tv_norm)) == ITERATIONS
    solve_numpy(prob, plain, params(model, tv_norm, rho=1.0))
    assert np.abs(ref.v - plain.v).max() > 100 * AGREE  # the relaxation is not ignored
    got = fields(fast)
    for name, r in fields(ref).items():
        assert np.abs(r - fields(st0)[name]).max() > 1e-3, f"{name} did not move"
        np.testing.assert_allclose(got[name], r, rtol=0, atol=AGREE, err_msg=name)


@pytest.mark.parametrize("model", ["l1_tv", "l1_tv_tv"])
def test_same_early_stop_relaxed(model: str) -> None:
    """The stopping rule measures x~ - x (the unrelaxed change) in both backends."""
    prob, st0 = random_case(model, False, seed=11)
    p = params(model, iterations=500, tolerance=2e-3)
    ref, fast = copy_state(st0), copy_state(st0)
    k = solve_numpy(prob, ref, p)
    assert k == solve_numba(prob, fast, p) and k < 500
    np.testing.assert_allclose(fast.v, ref.v, rtol=0, atol=AGREE)


@pytest.mark.parametrize("case", ["plain", "quad", "mass"])
def test_rho_one_is_the_plain_iteration_bit_for_bit(case: str) -> None:
    prob, st0 = CASES[case]("l1_tv_tv", 5)
    default = SolveParams(MODEL_SPECS["l1_tv_tv"], 0.05, 0.3, "isotropic", ITERATIONS, 0.0)
    for solve in (solve_numpy, solve_numba):
        a, b = copy_state(st0), copy_state(st0)
        solve(prob, a, default)
        solve(prob, b, params("l1_tv_tv", rho=1.0))
        for name, x in fields(a).items():
            assert np.array_equal(x, fields(b)[name]), name


@pytest.mark.parametrize(("model", "iterations"), [("l2_l2", 40), ("l1_tv", 300)])
def test_relaxed_iteration_reaches_the_plain_minimiser(model: str, iterations: int) -> None:
    """Both iterations converge to the same minimiser of the (convex) problem; rho = 1.7 is closer to it after the
    same number of steps (l2_l2 converges within ~150)."""
    prob, st0 = random_case(model, False, seed=2)
    long, plain, relaxed = (copy_state(st0) for _ in range(3))
    solve_numba(prob, long, params(model, rho=1.0, iterations=6000))
    solve_numba(prob, plain, params(model, rho=1.0, iterations=iterations))
    solve_numba(prob, relaxed, params(model, iterations=iterations))
    err_plain, err_relaxed = (float(np.abs(s.v - long.v).max()) for s in (plain, relaxed))
    assert err_relaxed < 0.5 * err_plain
    far = copy_state(st0)
    solve_numba(prob, far, params(model, iterations=6000))
    np.testing.assert_allclose(far.v, long.v, rtol=0, atol=2e-3)


def test_config_fields_reach_the_solver() -> None:
    cfg = FlowConfig.preset("stream_fast").replace(pd_relaxation=1.3)  # stream_fast: no stream_relaxation
    assert level_params(cfg, 0, 10).relaxation == pytest.approx(1.3)
    assert stream_schedule(cfg).pd_relaxation == pytest.approx(1.3)  # stream_relaxation 0: pd_relaxation's
    streamed = stream_schedule(cfg.replace(stream_relaxation=1.6))
    assert level_params(streamed, 0, 10).relaxation == pytest.approx(1.6)
    assert level_params(FlowConfig.preset("stream_fast"), 0, 10).relaxation == 1.0


@pytest.mark.parametrize("preset", ["quality", "balanced", "realtime", "fastest", "stream_fast", "stream_lite"])
def test_which_presets_relax_their_single_pairs(preset: str) -> None:
    """fastest solves over-relaxed at rho 1.3 on every level (the relax rule, 2026-12-08); quality, balanced and
    realtime did not pass, and the stream presets, fastest's fields otherwise, keep rho 1 on single pairs."""
    cfg = FlowConfig.preset(preset)
    want = 1.3 if preset == "fastest" else 1.0
    assert [level_params(cfg, level, cfg.iterations).relaxation for level in range(cfg.levels)] == pytest.approx(
        [want] * cfg.levels)


def test_stream_lite_relaxes_its_refinement_only() -> None:
    """stream_lite's stream refinement runs the over-relaxed iteration (rho 1.9, 18 iterations: task pdrelax and
    the lead); its single pairs and fallbacks the plain one, as fastest does."""
    cfg = FlowConfig.preset("stream_lite")
    refine = level_params(stream_schedule(cfg), cfg.finest_level, cfg.stream_iterations)
    assert (refine.relaxation, refine.iterations) == (pytest.approx(1.9), 18)
    single = level_params(cfg, cfg.finest_level, cfg.iterations)
    assert single.relaxation == 1.0
