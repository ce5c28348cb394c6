"""The validity mask (core/validity.py): masked pixels carry no data term, in every model and both backends."""

from __future__ import annotations

import numpy as np
import pytest
from synth import pair_from_flow, rotation_flow, texture

from flow_node.core.api import FlowEstimator, estimate_flow
from flow_node.core.config import FlowConfig
from flow_node.core.errors import InputError
from flow_node.core.models import MODEL_SPECS, PROX_DATA, prox_data_quadratic, weight_data, weight_quadratic
from flow_node.core.numba_backend import solve_numba
from flow_node.core.solver import PDState, Problem, SolveParams, solve_numpy
from flow_node.core.validity import as_masks, data_weight, fill_flow, fill_invalid

H, W = 96, 128


@pytest.mark.parametrize("data", ["l1", "l2"])
def test_weighted_prox_is_prox_of_weighted_term(data: str) -> None:
    """prox of tau m D on (a, c) == prox of tau D on the weighted pair, for m in [0, 1] (0: vt unchanged)."""
    rng = np.random.default_rng(1)
    a = rng.normal(size=(2, 20, 30)).astype(np.float32)
    c = rng.normal(size=(20, 30)).astype(np.float32)
    vt = rng.normal(size=(2, 20, 30)).astype(np.float32)
    m = rng.uniform(0.0, 1.0, (20, 30)).astype(np.float32)
    m[:5] = 0.0
    tau = 0.7
    folded = PROX_DATA[data](vt, *weight_data(a, c, m, data), tau)
    # the reference: the prox of (tau m) D, pixel by pixel with its own step
    direct = np.stack([PROX_DATA[data](vt[:, i:i + 1, j:j + 1], a[:, i:i + 1, j:j + 1], c[i:i + 1, j:j + 1],
                                       tau * float(m[i, j]))[:, 0, 0]
                       for i in range(20) for j in range(30)], axis=-1).reshape(2, 20, 30)
    np.testing.assert_allclose(folded, direct, atol=1e-5)
    np.testing.assert_array_equal(folded[:, :5], vt[:, :5])


def test_weighted_quadratic_prox() -> None:
    """The census data term's quadratic form times m: m = 0 leaves vt, m = 1 the unweighted prox."""
    rng = np.random.default_rng(2)
    g = rng.normal(size=(2, 2, 8, 8)).astype(np.float32)
    q = np.stack([(g[0] ** 2).sum(0), (g[0] * g[1]).sum(0), (g[1] ** 2).sum(0), g[0, 0], g[1, 1]])
    vt = rng.normal(size=(2, 8, 8)).astype(np.float32)
    m = np.ones((8, 8), np.float32)
    m[:4] = 0.0
    out = prox_data_quadratic(vt, weight_quadratic(q, m), 0.5)
    np.testing.assert_allclose(out[:, :4], vt[:, :4], atol=1e-6)
    np.testing.assert_allclose(out[:, 4:], prox_data_quadratic(vt, q, 0.5)[:, 4:], atol=1e-6)


@pytest.mark.parametrize("model", list(MODEL_SPECS))
def test_masked_solve_numba_matches_numpy(model: str) -> None:
    """A warp's problem with a masked hole: the numba kernels and the numpy reference agree to ~1e-5."""
    rng = np.random.default_rng(3)
    spec = MODEL_SPECS[model]
    a = rng.normal(0, 0.05, (2, 40, 50)).astype(np.float32)
    c = rng.normal(0, 0.05, (40, 50)).astype(np.float32)
    m = np.ones((40, 50), np.float32)
    m[10:25, 15:35] = 0.0
    prob = Problem(*weight_data(a, c, m, spec.data))
    params = SolveParams(spec, 0.05, 0.5 if spec.extended else 0.0, "isotropic", 30, 0.0)
    states = [PDState.zeros(spec, (40, 50)) for _ in range(2)]
    solve_numpy(prob, states[0], params)
    solve_numba(prob, states[1], params)
    np.testing.assert_allclose(states[0].v, states[1].v, atol=1e-5)
    np.testing.assert_allclose(states[0].y, states[1].y, atol=1e-5)


def test_data_weight_follows_frame1_mask() -> None:
    """Frame 1 invalid at x + v0 removes x's data term; frame 0 invalid at x too."""
    v0 = np.zeros((2, 20, 30), np.float32)
    v0[0] = 3.0
    valid0 = np.ones((20, 30), np.float32)
    valid1 = np.ones((20, 30), np.float32)
    valid1[:, 10] = 0.0
    valid0[5, 2] = 0.0
    m = data_weight(valid0, valid1, v0)
    assert (m[:, 7] == 0).all() and (m[:, 10] == 1).all()
    assert m[5, 2] == 0 and m[6, 2] == 1
    assert (m[:, -3:] == 0).all()  # x + 3 leaves the image


def test_fill_invalid_and_fill_flow() -> None:
    """Valid pixels unchanged, invalid ones filled from a smooth neighbourhood (a ramp stays near a ramp)."""
    ramp = np.tile(np.linspace(0, 1, 64, dtype=np.float32), (32, 1))
    valid = np.ones((32, 64), bool)
    valid[8:24, 20:40] = False
    out = fill_invalid(np.where(valid, ramp, 7.0).astype(np.float32), valid)
    np.testing.assert_array_equal(out[valid], ramp[valid])
    assert np.abs(out - ramp).max() < 0.15
    flow = np.zeros((2, 32, 64), np.float32)
    flow[0] = 2.0
    flow[:, ~valid] = -50.0
    filled = fill_flow(flow, valid.astype(np.float32))
    np.testing.assert_allclose(filled[0], 2.0, atol=1e-5)


def test_mask_errors() -> None:
    """Wrong size, dtype, count, or nothing valid: InputError naming the problem."""
    ok = np.ones((10, 12), np.uint8)
    assert as_masks(None, (10, 12)) is None
    m0, m1 = as_masks(ok[..., None], (10, 12))
    assert m0.dtype == bool and m0.all() and m1 is m0
    with pytest.raises(InputError, match="shape"):
        as_masks(np.ones((10, 11), bool), (10, 12))
    with pytest.raises(InputError, match="dtype"):
        as_masks(np.ones((10, 12), np.float32), (10, 12))
    with pytest.raises(InputError, match="every pixel"):
        as_masks(np.zeros((10, 12), bool), (10, 12))
    with pytest.raises(InputError, match="pair"):
        as_masks([ok, ok, ok], (10, 12))
    with pytest.raises(InputError, match="mask1"):
        as_masks((ok, "x"), (10, 12))
    with pytest.raises(InputError, match="mask"):
        estimate_flow(np.zeros((10, 12), np.float32), np.zeros((10, 12), np.float32), mask=np.ones((3, 3), bool))


def _garbage_pair() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A rotated texture whose frames hold garbage in a masked blob and a stripe (frame 1's moved)."""
    gt = rotation_flow(H, W, 1.5)
    i0, i1 = (f.astype(np.float32) for f in pair_from_flow(texture(H, W, seed=5), gt))
    rng = np.random.default_rng(4)
    valid0 = np.ones((H, W), bool)
    valid0[30:60, 40:75] = False
    valid0[:, 100:103] = False
    valid1 = np.roll(valid0, 4, axis=1)
    i0[~valid0] = rng.random(int((~valid0).sum()))
    i1[~valid1] = rng.random(int((~valid1).sum()))
    return i0, i1, gt, np.stack([valid0, valid1])


@pytest.mark.parametrize("backend", ["numpy", "numba"])
@pytest.mark.parametrize("photometric", ["normalise", "census"])
def test_mask_removes_garbage(backend: str, photometric: str) -> None:
    """With the mask the masked pixels' flow comes from their neighbours: far below the unmasked estimate's
    error there, and no worse elsewhere."""
    i0, i1, gt, valid = _garbage_pair()
    cfg = FlowConfig.preset("realtime").replace(backend=backend, photometric=photometric)
    est = FlowEstimator(cfg)
    inner = np.zeros((H, W), bool)
    inner[6:-6, 6:-6] = True
    hole, rest = inner & ~valid[0], inner & valid[0] & valid[1]
    err = {}
    for name, mask in (("off", None), ("on", (valid[0], valid[1].astype(np.uint8) * 255))):
        e = np.linalg.norm(est.estimate(i0, i1, mask=mask).flow - gt, axis=-1)
        err[name] = (float(e[hole].mean()), float(e[rest].mean()))
    assert err["on"][0] < 0.5 * err["off"][0], err
    assert err["on"][0] < 0.3, err
    assert err["on"][1] < 1.1 * err["off"][1] + 0.01, err


def test_mask_backends_agree() -> None:
    """The whole engine with a mask: numba and numpy give the same flow (up to float32 summation order)."""
    i0, i1, _, valid = _garbage_pair()
    flows = [estimate_flow(i0, i1, FlowConfig.preset("realtime").replace(backend=b), mask=(valid[0], valid[1]))
             for b in ("numpy", "numba")]
    assert np.abs(flows[0] - flows[1]).max() < 1e-3


def test_fill_reaches_far_pixels_and_scattered_masks_keep_coarse_data() -> None:
    """One valid pixel fills a whole level (the fill stops at the image's size); 2 % dead pixels leave the
    coarse levels most of their data (a level pixel's weight follows the valid fraction of its input)."""
    valid = np.zeros((30, 40), bool)
    valid[3, 5] = True
    np.testing.assert_allclose(fill_invalid(np.full((30, 40), 0.25, np.float32), valid), 0.25, atol=1e-6)
    from flow_node.core.pyramid import make_pyramid

    dead = np.random.default_rng(0).random((H, W)) > 0.02
    img = np.zeros((H, W), np.float32)
    pyr = make_pyramid(img, img, FlowConfig.preset("realtime"), valid=(dead, dead))
    coarse = pyr.valid(pyr.coarsest)
    assert coarse is not None
    zero = np.zeros((2,) + coarse[0].shape, np.float32)
    assert data_weight(*coarse, zero)[2:-2, 2:-2].mean() > 0.8
