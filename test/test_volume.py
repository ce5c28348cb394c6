"""The engine on volumes (core/volume.py, core/numba_volume.py): operators, the numba kernels against the numpy
reference, the flow's shape, order and convention, the incompressibility term, errors, and the CLI."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from flow_node.cli.estimate import main as estimate_main
from flow_node.core import estimate_flow
from flow_node.core.config import FlowConfig
from flow_node.core.errors import InputError
from flow_node.core.models import MODEL_SPECS, flow_divergence, flow_divergence_adjoint
from flow_node.core.operators import div, grad
from flow_node.core.solver import PDState, Problem, SolveParams, solve_numpy
from flow_node.core.volume import area_matrix, estimate_volume, linearise3, warp_source3

nv = pytest.importorskip("flow_node.core.numba_volume")
nvr = pytest.importorskip("flow_node.core.numba_volume_resample")

SHIFT = (1.5, -0.75, 0.5)  # x, y, z voxels
FAST = dict(levels=3, warps=3, iterations=30, finest_warps=3, finest_iterations=30, min_size=4, alpha=0.06,
            gradient_scheme="interpolated")


def texture(shape: tuple[int, int, int], shift: tuple[float, float, float] = (0.0, 0.0, 0.0),
            zoom: float = 1.0) -> np.ndarray:
    """A smooth sum of cosines sampled at the inverse of p -> c + zoom (p - c) + shift (x, y, z; c the centre):
    the pair (texture(s), texture(s, shift, zoom)) moves exactly by that map."""
    z, y, x = np.mgrid[0:shape[0], 0:shape[1], 0:shape[2]].astype(np.float64)
    cz, cy, cx = ((n - 1) / 2 for n in shape)
    x, y, z = (cx + (x - shift[0] - cx) / zoom, cy + (y - shift[1] - cy) / zoom, cz + (z - shift[2] - cz) / zoom)
    f = (np.cos(0.45 * x + 0.2 * y + 0.1 * z) + np.cos(0.3 * y - 0.4 * z + 1.0) + np.cos(0.5 * z + 0.25 * x + 2.0)
         + np.cos(0.2 * x - 0.35 * y + 0.3 * z + 0.5))
    return (0.5 + 0.1 * f).astype(np.float32)


def test_grad_div_adjoint_and_divergence_adjoint_3d() -> None:
    rng = np.random.default_rng(0)
    f = rng.normal(size=(5, 6, 7))
    p = rng.normal(size=(3, 5, 6, 7))
    assert np.isclose(np.sum(grad(f, dims=3) * p), -np.sum(f * div(p)))
    v, s = rng.normal(size=(3, 5, 6, 7)), rng.normal(size=(5, 6, 7))
    assert np.isclose(np.sum(flow_divergence(v) * s), np.sum(v * flow_divergence_adjoint(s, 3)))
    assert np.abs(flow_divergence(np.ones((3, 5, 6, 7)))).max() == 0.0  # a constant flow is divergence-free


def test_area_matrix_preserves_means() -> None:
    m = area_matrix(10, 4)
    assert np.allclose(m.sum(axis=1), 1.0)
    assert np.isclose(m.sum() * 10 / 4, 10.0)


@pytest.mark.parametrize("model", list(MODEL_SPECS))
@pytest.mark.parametrize("incompressibility", [0.0, 0.3])
def test_numba_solver_matches_numpy(model: str, incompressibility: float) -> None:
    rng = np.random.default_rng(1)
    shape = (6, 7, 9)
    a = rng.normal(size=(3,) + shape).astype(np.float32)
    c = rng.normal(size=shape).astype(np.float32)
    spec = MODEL_SPECS[model]
    for tv_norm in ("isotropic", "anisotropic"):
        params = SolveParams(spec, 0.05, 0.3, tv_norm, 40, 0.0, incompressibility)
        ref, fast = (PDState.zeros(spec, shape, incompressibility > 0) for _ in range(2))
        solve_numpy(Problem(a, c), ref, params)
        assert nv.solve_numba(Problem(a, c), fast, params) == 40
        assert np.abs(ref.v).max() > 0.1  # the test moves the flow
        assert np.abs(fast.v - ref.v).max() < 1e-5
        assert np.abs(fast.y - ref.y).max() < 1e-5
        if incompressibility:
            assert np.abs(fast.s - ref.s).max() < 1e-5


def test_numba_parallel_kernels_match_numpy(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(nv, "PARALLEL_MIN_PIXELS", 1)
    rng = np.random.default_rng(2)
    shape = (5, 6, 7)
    a, c = rng.normal(size=(3,) + shape).astype(np.float32), rng.normal(size=shape).astype(np.float32)
    params = SolveParams(MODEL_SPECS["l1_tv_tv"], 0.05, 0.3, "isotropic", 30, 0.0, 0.2)
    ref, fast = (PDState.zeros(params.spec, shape, True) for _ in range(2))
    solve_numpy(Problem(a, c), ref, params)
    nv.solve_numba(Problem(a, c), fast, params)
    assert np.abs(fast.v - ref.v).max() < 1e-5


@pytest.mark.parametrize("scheme", ["central", "interpolated"])
def test_numba_linearisation_matches_numpy(scheme: str) -> None:
    rng = np.random.default_rng(3)
    shape = (6, 8, 10)
    i0, i1 = rng.random(shape, dtype=np.float32), rng.random(shape, dtype=np.float32)
    v0 = rng.normal(scale=2.0, size=(3,) + shape).astype(np.float32)  # some points leave the volume
    src = warp_source3(i1, "central")
    gi0 = src[1:] * 0.5 if scheme == "interpolated" else None
    a_ref, c_ref = linearise3(i0, src, v0, gi0)
    a, c = nv.linearise_numba(i0, src, v0, gi0)
    assert (c_ref == 0).any() and (c_ref != 0).any()
    assert np.abs(a - a_ref).max() < 1e-5 and np.abs(c - c_ref).max() < 1e-5


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_pure_shift_shape_order_convention(backend: str) -> None:
    shape = (20, 24, 28)
    v0, v1 = texture(shape), texture(shape, SHIFT)  # I1(p + SHIFT) = I0(p)
    flow = estimate_flow(v0, v1, FlowConfig(backend=backend, **FAST))
    assert flow.shape == shape + (3,) and flow.dtype == np.float32
    inner = flow[4:-4, 4:-4, 4:-4].reshape(-1, 3)
    assert np.abs(np.median(inner, axis=0) - np.array(SHIFT)).max() < 0.05
    assert np.mean(np.linalg.norm(inner - np.array(SHIFT), axis=1)) < 0.1


def test_default_volume_config_on_a_thin_volume() -> None:
    shape = (12, 24, 28)  # a few slices: the default pyramid still has levels
    flow = estimate_flow(texture(shape), texture(shape, SHIFT))
    assert np.abs(np.median(flow[3:-3, 4:-4, 4:-4].reshape(-1, 3), axis=0) - np.array(SHIFT)).max() < 0.05


def test_uint8_and_uint16_volumes_give_the_same_flow() -> None:
    shape = (16, 18, 20)
    v0, v1 = texture(shape), texture(shape, SHIFT)
    cfg = FlowConfig(**FAST)
    f8 = estimate_volume(np.round(v0 * 255).astype(np.uint8), np.round(v1 * 255).astype(np.uint8), cfg).flow
    f16 = estimate_volume(np.round(v0 * 65535).astype(np.uint16), np.round(v1 * 65535).astype(np.uint16), cfg).flow
    assert np.abs(np.median(f8 - f16, axis=(0, 1, 2))).max() < 0.05


def test_incompressibility_lowers_the_divergence() -> None:
    shape = (16, 18, 20)
    f, v1 = texture(shape), texture(shape, zoom=1.06)  # true divergence 3 (s - 1) = 0.18 per frame
    free = estimate_volume(f, v1, FlowConfig(**FAST)).flow
    held = estimate_volume(f, v1, FlowConfig(incompressibility=5.0, **FAST)).flow
    div_free = np.abs(flow_divergence(np.moveaxis(free, -1, 0))[2:-2, 2:-2, 2:-2]).mean()
    div_held = np.abs(flow_divergence(np.moveaxis(held, -1, 0))[2:-2, 2:-2, 2:-2]).mean()
    assert div_free > 0.1
    assert div_held < 0.5 * div_free


def test_bad_volumes_are_clear_errors() -> None:
    v = texture((8, 9, 10))
    with pytest.raises(InputError, match="differ in shape"):
        estimate_flow(v, v[:, :, :-1])
    with pytest.raises(InputError, match="both be volumes"):
        estimate_flow(v, v[0])
    with pytest.raises(InputError, match="both be volumes"):
        estimate_flow(v[0], v)
    with pytest.raises(InputError, match="NaN"):
        estimate_flow(v, np.where(v > 0.5, np.nan, v))
    with pytest.raises(InputError, match="Z, Y, X"):
        estimate_volume(v[None], v[None])
    with pytest.raises(InputError, match="initial_flow"):
        estimate_flow(v, v, initial_flow=np.zeros(v.shape + (3,), np.float32))


def test_cli_volume_round_trip_npy_and_tiff(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    shape = (12, 24, 28)
    v0, v1 = texture(shape), texture(shape, SHIFT)
    np.save(tmp_path / "a.npy", v0)
    np.save(tmp_path / "b.npy", v1)
    for k, vol in enumerate((v0, v1)):
        assert cv2.imwritemulti(str(tmp_path / f"{k}.tif"), list(np.round(vol * 65535).astype(np.uint16)))
    sets = [f"--set={k}={v}" for k, v in FAST.items()]
    for inputs in (("a.npy", "b.npy"), ("0.tif", "1.tif")):
        out = tmp_path / f"{inputs[0]}.flow.npy"
        assert estimate_main([*(str(tmp_path / f) for f in inputs), "-o", str(out), *sets]) == 0
        flow = np.load(out)
        assert flow.shape == shape + (3,) and flow.dtype == np.float32
        assert np.abs(np.median(flow[3:-3, 4:-4, 4:-4].reshape(-1, 3), axis=0) - np.array(SHIFT)).max() < 0.1
    assert estimate_main([str(tmp_path / "a.npy"), str(tmp_path / "b.npy"), "-o", str(tmp_path / "x.flo")]) == 1
    assert "written as .npy" in capsys.readouterr().err
    assert not (tmp_path / "x.flo").exists()
    np.save(tmp_path / "c.npy", v1[:, :, :-2])
    assert estimate_main([str(tmp_path / "a.npy"), str(tmp_path / "c.npy"), "-o", str(tmp_path / "y.npy")]) == 1
    assert "differ in shape" in capsys.readouterr().err
    (tmp_path / "bad.npy").write_bytes(b"not an array")
    assert estimate_main([str(tmp_path / "bad.npy"), str(tmp_path / "b.npy"), "-o", str(tmp_path / "z.npy")]) == 1
    assert "not a .npy array" in capsys.readouterr().err
    assert math.isfinite(float(np.load(tmp_path / "a.npy.flow.npy").sum()))


def test_numba_resampling_matches_numpy() -> None:
    from flow_node.core.volume import linear_matrix, resample

    f = np.random.default_rng(4).random((2, 3, 9, 10, 11), dtype=np.float32)
    for shape, matrix in (((5, 4, 6), area_matrix), ((17, 20, 13), linear_matrix), ((9, 5, 11), area_matrix)):
        ref = resample(f, shape, matrix)
        fast = nvr.resample_numba(f, shape, matrix)
        assert fast.shape == ref.shape == (2, 3) + shape
        assert np.abs(fast - ref).max() < 1e-5


@pytest.mark.parametrize("model", ["l2_l2", "l1_tv", "l1_tv_tv"])
def test_numpy_solver_decreases_the_3d_energy_with_incompressibility(model: str) -> None:
    """The reference itself (not only numba = numpy): on a volume, with the div v block, the primal energy
    (models.energy, penalty included) falls below its value at zero and keeps falling, and the end point is
    a minimum: no small random change of v lowers the (convex) energy."""
    from flow_node.core.models import energy

    rng = np.random.default_rng(5)
    shape = (6, 7, 8)
    a = rng.normal(size=(3,) + shape).astype(np.float32)
    c = rng.normal(size=shape).astype(np.float32)
    spec, alpha, beta = MODEL_SPECS[model], 0.5, 2.0
    state = PDState.zeros(spec, shape, True)

    def e(st: PDState) -> float:
        return energy(spec, st.v, st.w, a, c, alpha, 0.3, "isotropic", incompressibility=beta)

    e0 = e(state)
    solve_numpy(Problem(a, c), state, SolveParams(spec, alpha, 0.3, "isotropic", 50, 0.0, beta))
    e50 = e(state)
    solve_numpy(Problem(a, c), state, SolveParams(spec, alpha, 0.3, "isotropic", 1000, 0.0, beta))
    e_end = e(state)
    assert e_end < 0.9 * e0
    assert e_end <= e50 + 1e-3 * abs(e50)
    for _ in range(5):
        moved = PDState(state.v + rng.normal(scale=0.02, size=state.v.shape).astype(np.float32), state.y,
                        state.w, state.z, state.s)
        assert e(moved) > e_end - 1e-3 * abs(e_end)
