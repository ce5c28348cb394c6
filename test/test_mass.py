"""Mass preservation (the continuity equation as the data term): the operator A and its adjoint, the
linearisation, the numba kernels against the numpy reference, the config rule, the suite's exactly rendered
density pairs, and that the model recovers a divergent motion that brightness constancy cannot."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from synth import texture

from flow_node.core.api import FlowEstimator
from flow_node.core.bregman import bregman
from flow_node.core.config import MASS_SCHEDULE, MODELS, FlowConfig
from flow_node.core.errors import ConfigError
from flow_node.core.models import MODEL_SPECS, apply_a, apply_a_adjoint, energy, mass_residual
from flow_node.core.numba_backend import solve_numba
from flow_node.core.operators import (
    jacobian_central,
    jacobian_central_adjoint,
    linearise,
    mass_linearise,
    warp_source,
)
from flow_node.core.solver import PDState, Problem, SolveParams, solve_numpy

H, W = 36, 50
ITERATIONS = 40
AGREE = 1e-5


def test_jacobian_and_a_adjoints() -> None:
    rng = np.random.default_rng(0)
    v, q = rng.normal(size=(2, H, W)), rng.normal(size=(2, 2, H, W))
    assert np.sum(jacobian_central(v) * q) == pytest.approx(np.sum(v * jacobian_central_adjoint(q)), rel=1e-12)
    a, m, p = rng.normal(size=(2, H, W)), rng.normal(size=(2, 2, H, W)), rng.normal(size=(H, W))
    assert np.sum(apply_a(v, a, m) * p) == pytest.approx(np.sum(v * apply_a_adjoint(p, a, m)), rel=1e-12)


def test_jacobian_of_a_linear_field_is_exact_inside() -> None:
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    v = np.stack([0.3 * x - 0.2 * y, 0.1 * x + 0.5 * y])
    j = jacobian_central(v)
    np.testing.assert_allclose(j[:, :, 1:-1, 1:-1], np.array([[0.3, -0.2], [0.1, 0.5]])[:, :, None, None]
                               * np.ones((1, 1, H - 2, W - 2)), atol=1e-12)


def test_linearisation_without_warp_is_the_continuity_equation() -> None:
    """v0 = 0: rho(v) = I1 - I0 + grad I1 . v + I1 div v (central differences)."""
    i0, i1 = texture(H, W, seed=1).image.astype(np.float32), texture(H, W, seed=2).image.astype(np.float32)
    v0 = np.zeros((2, H, W), np.float32)
    a, c = linearise(i0, warp_source(i1, "central", "bspline"), None, v0, "central")
    a_m, m, c_m = mass_linearise(i0, a, c, v0)
    np.testing.assert_allclose(a_m, a, atol=1e-6)
    np.testing.assert_allclose(c_m, c, atol=1e-6)
    np.testing.assert_allclose(m[0, 1], 0.0, atol=0)
    np.testing.assert_allclose(m[0, 0], m[1, 1], atol=0)
    v = np.random.default_rng(3).normal(size=(2, H, W)).astype(np.float32)
    jac = jacobian_central(v)
    np.testing.assert_allclose(mass_residual(v, a_m, m, c_m), c + a[0] * v[0] + a[1] * v[1]
                               + m[0, 0] * (jac[0, 0] + jac[1, 1]), atol=1e-5)


def random_case(model: str, data_bregman: bool, seed: int) -> tuple[Problem, PDState]:
    rng = np.random.default_rng(seed)
    f32 = np.float32
    a = (0.2 * rng.standard_normal((2, H, W))).astype(f32)
    m = (0.8 + 0.3 * rng.standard_normal((2, 2, H, W))).astype(f32)
    c = (0.05 * rng.standard_normal((H, W))).astype(f32)
    b = (0.3 * rng.standard_normal((2, H, W))).astype(f32) if data_bregman else None
    st = PDState.zeros(MODEL_SPECS[model], (H, W))
    st.v = (0.5 * rng.standard_normal((2, H, W))).astype(f32)
    st.y = np.clip(0.4 * rng.standard_normal(st.y.shape), -0.7, 0.7).astype(f32)
    st.p = (0.5 * rng.standard_normal((H, W))).astype(f32)
    if st.w is not None:
        st.w = (0.1 * rng.standard_normal(st.w.shape)).astype(f32)
    if st.z is not None:
        st.z = (0.1 * rng.standard_normal(st.z.shape)).astype(f32)
    return Problem(a, c, b, m=m), st


def copy_state(st: PDState) -> PDState:
    return dataclasses.replace(st, **{f.name: None if getattr(st, f.name) is None else getattr(st, f.name).copy()
                                      for f in dataclasses.fields(st)})


@pytest.mark.parametrize("bregman_term", [False, True], ids=["plain", "bregman"])
@pytest.mark.parametrize("tv_norm", ["isotropic", "anisotropic"])
@pytest.mark.parametrize("model", MODELS)
def test_numba_matches_numpy_on_mass(model: str, tv_norm: str, bregman_term: bool) -> None:
    prob, st0 = random_case(model, bregman_term, seed=MODELS.index(model))
    alpha = 0.002 if model.startswith("l2") else 0.05
    params = SolveParams(MODEL_SPECS[model], alpha, 0.3, tv_norm, ITERATIONS, 0.0)
    ref, fast = copy_state(st0), copy_state(st0)
    assert solve_numpy(prob, ref, params) == ITERATIONS
    assert solve_numba(prob, fast, params) == ITERATIONS
    assert_states_agree(ref, fast, st0)


def assert_states_agree(ref: PDState, fast: PDState, start: PDState | None = None) -> None:
    """numpy's and numba's primal and dual variables agree to AGREE (and, given ``start``, each has moved)."""
    for name in ("v", "y", "w", "z", "p"):
        r, f = getattr(ref, name), getattr(fast, name)
        if r is None:
            assert f is None
            continue
        assert np.max(np.abs(r - f)) < AGREE, name
        if start is not None:
            assert np.max(np.abs(r - getattr(start, name))) > 1e-3, f"{name} did not move"


@pytest.mark.parametrize("model", MODELS)
def test_mass_solve_lowers_the_energy(model: str) -> None:
    """From zero flow the primal-dual steps (diagonally preconditioned) decrease the model's energy on a
    mass problem, and Bregman steps run on it."""
    prob, _ = random_case(model, False, seed=7)
    spec = MODEL_SPECS[model]
    alpha = 0.002 if model.startswith("l2") else 0.05
    params = SolveParams(spec, alpha, 0.3, "isotropic", 300, 0.0)
    st = PDState.zeros(spec, (H, W))
    e0 = energy(spec, st.v, st.w, prob.a, prob.c, alpha, 0.3, "isotropic", m=prob.m)
    solve_numpy(prob, st, params)
    e1 = energy(spec, st.v, st.w, prob.a, prob.c, alpha, 0.3, "isotropic", m=prob.m)
    assert e1 < 0.5 * e0
    assert bregman(prob, st, params, solve_numpy, 2) == 600


def test_config_constraint_rules() -> None:
    cfg = FlowConfig().replace(constraint="mass")
    assert cfg.photometric == "density"
    assert FlowConfig().with_overrides(["constraint=mass"]).photometric == "density"
    assert FlowConfig().replace(constraint="mass", photometric="none").photometric == "none"
    # the fine pyramid comes with the constraint unless given; re-selecting mass keeps what was set
    assert {k: getattr(cfg, k) for k in MASS_SCHEDULE} == MASS_SCHEDULE != {k: getattr(FlowConfig(), k)
                                                                            for k in MASS_SCHEDULE}
    assert FlowConfig().replace(constraint="mass", warps=4).warps == 4
    assert cfg.replace(constraint="mass", levels=5).replace(constraint="mass").levels == 5
    with pytest.raises(ConfigError, match="constraint 'mass' needs photometric"):
        FlowConfig(constraint="mass")
    with pytest.raises(ConfigError, match="constraint 'mass' needs photometric"):
        FlowConfig().replace(constraint="mass", photometric="census")
    with pytest.raises(ConfigError, match="constraint"):
        FlowConfig().replace(constraint="volume")


def test_mass_regime_pairs_preserve_mass() -> None:
    """The rendering is exact: I1(phi(x)) det(D phi)(x) = I0(x) on the continuous maps (checked at the
    pixel grid's images), and the mass in the interior is conserved up to what crosses the border."""
    from bench.suite.mass import MAPS

    rng = np.random.default_rng(5)
    x = np.stack(np.meshgrid(np.arange(60.0), np.arange(40.0)), axis=-1)
    for name, make in MAPS.items():
        phi = make(rng, np.array([29.5, 19.5]))
        np.testing.assert_allclose(phi.inverse(phi.forward(x)), x, atol=1e-9, err_msg=name)
        det = phi.det(x)
        assert np.all(det > 0.5), name
        # finite-difference Jacobian determinant of the forward map agrees with the analytic one
        e = 1e-5
        dx = (phi.forward(x + [e, 0]) - phi.forward(x - [e, 0])) / (2 * e)
        dy = (phi.forward(x + [0, e]) - phi.forward(x - [0, e])) / (2 * e)
        np.testing.assert_allclose(dx[..., 0] * dy[..., 1] - dx[..., 1] * dy[..., 0], det, atol=1e-6, err_msg=name)


def test_mass_model_recovers_a_source_that_brightness_constancy_misreads() -> None:
    from bench.suite.mass import mass_pair

    i0, i1, gt, _ = mass_pair(1, 1)  # a radial source or sink, 320x240
    base = FlowConfig(backend="numba")
    errors = {}
    for name, cfg in (("brightness", base), ("mass", base.replace(constraint="mass"))):
        flow = FlowEstimator(cfg).estimate(i0.astype(np.float32), i1.astype(np.float32)).flow
        errors[name] = float(np.linalg.norm(flow - gt, axis=-1)[8:-8, 8:-8].mean())
    assert errors["mass"] < 0.5 * errors["brightness"], errors


def test_cli_reaches_the_mass_constraint(tmp_path) -> None:  # noqa: ANN001
    """``flow_estimate --set constraint=mass`` runs the mass model (density mode implied) and writes the flow;
    with a photometric mode that changes mass it fails with the config's one-line reason."""
    import os
    import subprocess
    import sys

    import cv2

    from bench.suite.mass import mass_pair
    from flow_node.core.flowio import read_flo

    i0, i1, gt, _ = mass_pair(1, 1, size=(96, 72))
    for name, img in (("a.png", i0), ("b.png", i1)):
        cv2.imwrite(str(tmp_path / name), np.rint(np.clip(img, 0, 1) * 65535).astype(np.uint16))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    base = [sys.executable, "-m", "flow_node.cli.estimate", str(tmp_path / "a.png"), str(tmp_path / "b.png"),
            "-o", str(tmp_path / "f.flo"), "--set", "levels=3"]
    ok = subprocess.run([*base, "--set", "constraint=mass"], capture_output=True, text=True, env=env, check=False)
    assert ok.returncode == 0, ok.stderr
    assert read_flo(tmp_path / "f.flo").shape == gt.shape
    bad = subprocess.run([*base, "--set", "constraint=mass", "--set", "photometric=normalise"], capture_output=True,
                         text=True, env=env, check=False)
    assert bad.returncode != 0 and "constraint 'mass' needs photometric" in bad.stderr


def test_density_mode_is_one_gain_for_both_frames() -> None:
    """photometric=density keeps mass: both frames times the same factor, nothing subtracted, and a density
    change between the frames is not undone as an exposure change."""
    from flow_node.core.photometric import stage

    rng = np.random.default_rng(2)
    i0 = rng.uniform(0.1, 0.7, (60, 80)).astype(np.float32)
    i1 = (i0 * np.float32(1.2)).astype(np.float32)  # a uniform compression: 20 % more density
    (d0, d1), _ = stage(i0, i1, "density")
    gain = d0 / i0
    np.testing.assert_allclose(gain, gain.flat[0], rtol=1e-5)
    np.testing.assert_allclose(d1 / i1, gain.flat[0], rtol=1e-5)


@pytest.mark.parametrize("model", ["l2_tv", "l1_tv"])
def test_bregman_steps_keep_the_mass_term(model: str) -> None:
    """Every Bregman step solves the mass problem (M passed through); for L2 data its shifted constant is
    c + rho(v_k) with rho(v) = A v + c, the continuity equation's residual (not brightness constancy's a . v + c)."""
    rng = np.random.default_rng(3)
    a = rng.normal(size=(2, 12, 14)).astype(np.float32)
    m = rng.normal(size=(2, 2, 12, 14)).astype(np.float32)
    c = rng.normal(size=(12, 14)).astype(np.float32)
    problem = Problem(a, c, m=m)
    state = PDState.zeros(MODEL_SPECS[model], (12, 14))
    state.v = rng.normal(size=(2, 12, 14)).astype(np.float32)
    seen: list[Problem] = []

    def solve(step: Problem, st: PDState, p: SolveParams) -> int:
        seen.append(step)
        return 1

    p = SolveParams(MODEL_SPECS[model], 0.05, 0.0, "isotropic", 10, 0.0)
    assert bregman(problem, state, p, solve, 2) == 2
    assert all(s.m is m for s in seen)
    if model == "l2_tv":
        np.testing.assert_allclose(seen[0].c, c + apply_a(state.v, a, m) + c, rtol=1e-5, atol=1e-5)
