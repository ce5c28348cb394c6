"""The edge-weighted TV (edges.py; docs/engine.md, "Edge-weighted TV"): g |grad v| with g from a level's frame 0,
whose only trace in the primal-dual iteration is the radius g of the dual ball (models.project_dual_tv)."""

from __future__ import annotations

import numpy as np
import pytest
from synth import texture

from flow_node import FlowConfig
from flow_node.core.config import MODELS
from flow_node.core.edges import MASK_REACH, edge_weight, level_edge_weight, unweighted_near_invalid
from flow_node.core.errors import ConfigError
from flow_node.core.models import MODEL_SPECS, project_dual_tv
from flow_node.core.numba_backend import solve_numba
from flow_node.core.solver import PDState, Problem, SolveParams, solve_numpy

H, W = 40, 56
ITERATIONS = 40
AGREE = 1e-5


def weight() -> np.ndarray:
    """A non-trivial edge weight: a texture with a bright rectangle (strong edges) -> g in [0.1, 1]."""
    img = texture(H, W, seed=5).image.astype(np.float32)
    img[10:30, 20:44] += 0.5
    return edge_weight(img, 1.0, 1.0, 0.1)


def case(model: str, g: np.ndarray | None, seed: int = 0) -> tuple[Problem, PDState]:
    rng = np.random.default_rng(seed)
    a = (0.2 * rng.standard_normal((2, H, W))).astype(np.float32)
    c = (0.05 * rng.standard_normal((H, W))).astype(np.float32)
    st = PDState.zeros(MODEL_SPECS[model], (H, W))
    st.v = (0.5 * rng.standard_normal((2, H, W))).astype(np.float32)
    if st.w is not None:
        st.w = (0.1 * rng.standard_normal(st.w.shape)).astype(np.float32)
    return Problem(a, c, g=g), st


def copy(st: PDState) -> PDState:
    return PDState(*(None if x is None else x.copy() for x in (st.v, st.y, st.w, st.z)))


def params(model: str, tv_norm: str = "isotropic") -> SolveParams:
    alpha = 0.002 if model.startswith("l2") else 0.05
    return SolveParams(MODEL_SPECS[model], alpha, 0.3, tv_norm, ITERATIONS, 0.0)


def test_the_weight_is_in_its_range_and_ignores_the_contrast() -> None:
    g = weight()
    assert g.dtype == np.float32 and g.shape == (H, W)
    assert g.min() == pytest.approx(0.1) and 0.5 < g.max() <= 1.0  # floored at the rectangle's edges
    img = texture(H, W, seed=5).image.astype(np.float32)
    np.testing.assert_allclose(edge_weight(0.2 * img + 0.3, 2.0, 1.0, 0.05), edge_weight(img, 2.0, 1.0, 0.05),
                               atol=1e-5)
    assert np.all(edge_weight(np.full((H, W), 0.4, np.float32), 2.0, 1.0, 0.1) == 1.0)  # nothing to weight
    assert level_edge_weight(img, FlowConfig(), 3) is None  # off by default
    cfg = FlowConfig(tv_edge_weight=2.0, tv_edge_power=1.0, tv_edge_floor=0.05)
    assert np.array_equal(level_edge_weight(img, cfg, 1), edge_weight(img, 2.0, 1.0, 0.05))


def test_pixels_without_data_keep_plain_tv() -> None:
    g = weight()
    valid = np.ones((H, W), np.float32)
    valid[12:20, 22:30] = 0.0
    out = unweighted_near_invalid(g, valid)
    r = MASK_REACH
    assert np.all(out[12 - r:20 + r, 22 - r:30 + r] == 1.0)
    far = np.ones((H, W), bool)
    far[12 - r:20 + r, 22 - r:30 + r] = False
    assert np.array_equal(out[far], g[far]) and np.any(g[~far] < 1.0)
    cfg = FlowConfig(tv_edge_weight=1.0, tv_edge_power=1.0)
    assert np.array_equal(level_edge_weight(g, cfg, 1, valid), unweighted_near_invalid(level_edge_weight(g, cfg, 1),
                                                                                          valid))
    assert level_edge_weight(g, cfg, 0) is None  # plain TV below tv_edge_min_level (default 1)


def test_the_fields_are_validated() -> None:
    for bad in (dict(tv_edge_weight=-1.0), dict(tv_edge_power=0.0), dict(tv_edge_floor=0.0),
                dict(tv_edge_floor=1.5)):
        with pytest.raises(ConfigError):
            FlowConfig(**bad)


def test_projection_onto_a_ball_of_per_pixel_radius() -> None:
    rng = np.random.default_rng(1)
    yt = rng.standard_normal((2, 2, H, W)).astype(np.float32)
    g = weight()
    iso = project_dual_tv(yt, g, "isotropic")
    norm = np.sqrt(np.sum(iso * iso, axis=(0, 1)))
    assert np.all(norm <= g * (1 + 1e-6)) and np.any(norm > 0.99 * g)
    inside = np.sqrt(np.sum(yt * yt, axis=(0, 1))) <= g
    assert np.array_equal(iso[:, :, inside], yt[:, :, inside])  # inside the ball: unchanged
    assert np.all(np.abs(project_dual_tv(yt, g, "anisotropic")) <= g)


@pytest.mark.parametrize("tv_norm", ["isotropic", "anisotropic"])
@pytest.mark.parametrize("model", MODELS)
def test_numba_matches_numpy_with_the_weight_and_the_weight_matters(model: str, tv_norm: str) -> None:
    prob, st0 = case(model, weight(), seed=MODELS.index(model))
    ref, fast, plain = copy(st0), copy(st0), copy(st0)
    solve_numpy(prob, ref, params(model, tv_norm))
    solve_numba(prob, fast, params(model, tv_norm))
    solve_numpy(Problem(prob.a, prob.c), plain, params(model, tv_norm))
    for r, f in zip((ref.v, ref.y, ref.w, ref.z), (fast.v, fast.y, fast.w, fast.z), strict=True):
        if r is not None:
            np.testing.assert_allclose(f, r, rtol=0, atol=AGREE)
    assert np.abs(ref.v - plain.v).max() > 100 * AGREE  # the weight is not ignored


@pytest.mark.parametrize("model", MODELS)
def test_unit_weight_is_the_unweighted_solve_bit_for_bit(model: str) -> None:
    """g = 1 everywhere and no g are the same flows in both backends (the off path: today's arithmetic)."""
    prob, st0 = case(model, None, seed=3)
    ones = Problem(prob.a, prob.c, g=np.ones((H, W), np.float32))
    for solve in (solve_numpy, solve_numba):
        off, unit = copy(st0), copy(st0)
        solve(prob, off, params(model))
        solve(ones, unit, params(model))
        for x, y in zip((off.v, off.y, off.w, off.z), (unit.v, unit.y, unit.w, unit.z), strict=True):
            assert (x is None and y is None) or np.array_equal(x, y)


@pytest.mark.parametrize("tv_norm", ["isotropic", "anisotropic"])
@pytest.mark.parametrize("model", ["l2_tv", "l1_tv", "l1_tv_l2", "l1_tv_tv"])
def test_the_weighted_dual_stays_in_its_ball(model: str, tv_norm: str) -> None:
    g = weight()
    prob, st0 = case(model, g, seed=4)
    for solve in (solve_numpy, solve_numba):
        st = copy(st0)
        solve(prob, st, params(model, tv_norm))
        if tv_norm == "isotropic":
            assert np.all(np.sqrt(np.sum(st.y.astype(np.float64) ** 2, axis=(0, 1))) <= g * (1 + 1e-5))
        else:
            assert np.all(np.abs(st.y) <= g)
        assert np.any(np.abs(st.y) > 0.5 * g)  # the ball is reached somewhere: the radius constrains


def test_a_flow_jump_moves_to_the_image_edge_with_the_weight() -> None:
    """Two regions whose data term pins u = 1 (left) and u = 0 (right), with a data-free band between them (an
    occlusion-like gap): plain TV is indifferent to where in the band the flow jumps (every monotone profile
    costs the same), the weighted TV puts the jump on the image's edge at column 16 inside the band. The flow
    in the band is then the right one on either side of the edge."""
    n = 32
    img = (0.1 * texture(n, n, seed=1).image).astype(np.float32)
    img[:, 16:] += 0.5
    g = edge_weight(img, 1.0, 1.0, 0.1)
    rng = np.random.default_rng(0)
    angle = rng.uniform(0, 2 * np.pi, (n, n))
    a = (0.1 * np.stack([np.cos(angle), np.sin(angle)])).astype(np.float32)
    a[:, :, 10:22] = 0.0  # no data in the band
    truth = np.zeros((2, n, n), np.float32)
    truth[0, :, :16] = 1.0
    c = (-(a * truth).sum(0)).astype(np.float32)
    spec = MODEL_SPECS["l1_tv"]
    errors = []
    for weights in (None, g):
        for solve in (solve_numpy, solve_numba):
            st = PDState.zeros(spec, (n, n))
            solve(Problem(a, c, g=weights), st, SolveParams(spec, 0.05, 0.3, "isotropic", 500, 0.0))
            errors.append(float(np.mean(np.linalg.norm(st.v - truth, axis=0)[:, 10:22])))
    assert errors[0] == pytest.approx(errors[1], abs=1e-3) and errors[2] == pytest.approx(errors[3], abs=1e-3)
    assert errors[2] < 0.5 * errors[0], errors


@pytest.mark.parametrize("model", ["l2_l2", "l1_tv", "l1_tv_tv"])
@pytest.mark.parametrize("tv_norm", ["isotropic", "anisotropic"])
def test_the_energy_weighs_its_first_regulariser_term(model: str, tv_norm: str) -> None:
    """models.energy with the edge weight (what the mass model's slow-mode step compares, solver.shift_slow_modes):
    a weight of ones is the plain energy, and a weight of one half halves the first regulariser term only."""
    from flow_node.core.models import energy

    problem, st = case(model, None)
    spec = MODEL_SPECS[model]
    args = (spec, st.v, st.w, problem.a, problem.c, 0.05, 0.5, tv_norm)
    plain = energy(*args)
    assert energy(*args, weight=np.ones((H, W), np.float32)) == pytest.approx(plain, rel=1e-12)
    zero_reg = energy(spec, st.v, st.w, problem.a, problem.c, 0.0, 0.5, tv_norm)  # data (+ second term) alone
    half = energy(*args, weight=np.full((H, W), 0.5, np.float32))
    assert half - zero_reg == pytest.approx(0.5 * (plain - zero_reg), rel=1e-9)
    assert plain - zero_reg > 0.0
