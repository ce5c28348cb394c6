"""The paper's joint model (core/joint.py): the flow's data term with the images eliminated, J_gamma, in both
backends; the images reconstructed for a flow (denoised along the motion, filled in where data is missing)."""

from __future__ import annotations

import numpy as np
import pytest
from synth import constant_flow, pair_from_flow, texture

from flow_node.core.config import FlowConfig
from flow_node.core.errors import ConfigError, InputError
from flow_node.core.joint import JointParams, JointState, joint_energy, reconstruct, reconstruct_images, warp_operator
from flow_node.core.models import MODEL_SPECS, joint_data, prox_data_joint, prox_data_l1
from flow_node.core.numba_backend import solve_numba
from flow_node.core.refine import level_params
from flow_node.core.solver import PDState, Problem, SolveParams, solve_numpy


def test_joint_data_is_the_eliminated_images() -> None:
    """gamma J_gamma(d) = min over (u0, u1) of 1/2 (u0 - f0)^2 + 1/2 (u1 - f1)^2 + gamma |u1 - u0| (brute force)."""
    gamma = 0.03
    grid = np.linspace(-0.3, 0.3, 1201)
    for d in (-0.2, -0.05, 0.0, 0.01, 0.04, 0.06, 0.15):
        u0, u1 = np.meshgrid(grid, grid + d, indexing="ij")  # f0 = 0, f1 = d
        brute = float((0.5 * u0**2 + 0.5 * (u1 - d) ** 2 + gamma * np.abs(u1 - u0)).min())
        assert gamma * float(joint_data(np.array(d), gamma)) == pytest.approx(brute, abs=2e-4)


def test_prox_joint_is_the_argmin_and_tends_to_l1() -> None:
    rng = np.random.default_rng(0)
    a = rng.normal(0, 0.2, (2, 6, 7))
    c = rng.normal(0, 0.05, (6, 7))
    vt = rng.normal(0, 1.0, (2, 6, 7))
    tau, gamma = 0.8, 0.02
    out = prox_data_joint(vt, a, c, tau, gamma)

    def objective(v: np.ndarray) -> np.ndarray:
        return 0.5 * ((v - vt) ** 2).sum(0) + tau * joint_data(a[0] * v[0] + a[1] * v[1] + c, gamma)

    for _ in range(20):  # no perturbation does better
        assert (objective(out) <= objective(out + rng.normal(0, 1e-3, out.shape)) + 1e-12).all()
    np.testing.assert_allclose(prox_data_joint(vt, a, c, tau, 1e-12), prox_data_l1(vt, a, c, tau), atol=1e-6)


@pytest.mark.parametrize("model", ["l1_tv", "l1_tv_l2", "l1_tv_tv"])
def test_joint_solve_numba_matches_numpy(model: str) -> None:
    rng = np.random.default_rng(1)
    spec = MODEL_SPECS[model]
    prob = Problem(rng.normal(0, 0.1, (2, 30, 40)).astype(np.float32), rng.normal(0, 0.05, (30, 40)).astype(np.float32))
    params = SolveParams(spec, 0.06, 0.5 if spec.extended else 0.0, "isotropic", 30, 0.0, gamma=0.02)
    states = [PDState.zeros(spec, (30, 40)) for _ in range(2)]
    solve_numpy(prob, states[0], params)
    solve_numba(prob, states[1], params)
    np.testing.assert_allclose(states[0].v, states[1].v, atol=1e-5)
    plain = PDState.zeros(spec, (30, 40))
    solve_numba(prob, plain, SolveParams(spec, 0.06, params.alpha1, "isotropic", 30, 0.0))
    assert np.abs(plain.v - states[1].v).max() > 1e-3  # gamma changes the solution


def test_joint_config() -> None:
    cfg = FlowConfig.preset("joint")
    assert cfg.reconstruction == "joint" and MODEL_SPECS[cfg.model].data == "l1"
    # every level's solve gets the joint data term's weight, and no incompressibility (a positional slip once
    # passed image_gamma as SolveParams' 7th field, the incompressibility: the numba backend solved plain L1)
    for level in range(cfg.levels):
        params = level_params(cfg, level, 6)
        assert (params.gamma, params.incompressibility) == (cfg.image_gamma, 0.0)
    assert level_params(FlowConfig.preset("realtime"), 0, 6).gamma == 0.0
    with pytest.raises(ConfigError, match="L1 data term"):
        FlowConfig(model="l2_tv", reconstruction="joint")


def test_reconstruct_images_denoises_and_fills_missing_data() -> None:
    """With the true flow: the reconstructed frames are closer to the clean ones than the noisy data, a blob
    missing from frame 0 is filled from frame 1 along the motion, and the primal-dual solve lowers the energy."""
    h, w = 60, 80
    gt = constant_flow(h, w, 1.5, -0.75)
    clean = [f.astype(np.float32) for f in pair_from_flow(texture(h, w, seed=2), gt)]
    rng = np.random.default_rng(3)
    noisy = [(f + rng.normal(0, 0.02, f.shape)).astype(np.float32) for f in clean]
    valid0 = np.ones((h, w), bool)
    valid0[20:35, 30:50] = False
    noisy[0][~valid0] = 1.0  # garbage
    u0, u1 = reconstruct_images(noisy[0], noisy[1], gt, (valid0, np.ones((h, w), bool)), alpha=0.002, gamma=0.05)
    inner = (slice(4, -4), slice(4, -4))
    err_noisy = np.abs(noisy[1] - clean[1])[inner].mean()
    assert np.abs(u1 - clean[1])[inner].mean() < 0.85 * err_noisy
    assert np.abs(u0 - clean[0])[~valid0].mean() < 1.5 * err_noisy  # garbage was ~0.5 off
    f = np.stack(noisy)
    m = np.stack([valid0, np.ones((h, w), bool)]).astype(np.float32)
    v = np.moveaxis(gt, -1, 0)
    p = JointParams(0.002, 0.05, 50)
    start = JointState.start(*f)
    e0 = joint_energy(start.u, f, m, warp_operator(v), p)
    assert joint_energy(reconstruct(start, f, m, v, p).u, f, m, warp_operator(v), p) < e0
    with pytest.raises(InputError, match="do not match"):
        reconstruct_images(noisy[0], noisy[1], gt[:10])
