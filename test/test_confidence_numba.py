"""The numba confidence (numba_confidence.confidence_numba) against the numpy reference
(confidence.confidence), the oracle: random frames and flows that leave the image in places, and a pair
rendered exactly with the realtime preset's flow; rows run serially and in parallel; the backends' wiring
(Backend.confidence, FlowEstimator.confidence, the stream's FlowOutput.confidence); the same for the
confidence at points only (numba_confidence.confidence_at_numba against confidence.confidence_at: each
point's box alone, or the map near dense points) and where a mask is True (confidence_numba with ``where``)."""

from __future__ import annotations

import math

import numba
import numpy as np
import pytest
from test_fusion_numba import REMAP_EXACT

from flow_node.bag.motion_scenes import motion_scene
from flow_node.bag.scenes import render_grey_pair
from flow_node.core import FlowEstimator, numba_backend, numba_confidence
from flow_node.core.backends import NUMPY, select_backend
from flow_node.core.confidence import confidence, confidence_at
from flow_node.core.config import FlowConfig
from flow_node.core.errors import InputError
from flow_node.core.numba_confidence import confidence_at_numba, confidence_numba
from flow_node.pipeline.stream import FlowStream, StreamSettings

# The kernels sample bilinearly at the exact position, as OpenCV 5's remap (the reference's) does; OpenCV 4.x (the
# Ubuntu 24.04 venv) snaps the reference's positions to 1/32 px, which moves its confidence by up to ~0.01
# (measured with 4.6: max 0.0084, mean 0.0006 on these cases): there the bound is on that scale instead.
TOL = 1e-5 if REMAP_EXACT else 2e-2
MEAN_TOL = 1e-5 if REMAP_EXACT else 2e-3


def assert_matches(out: np.ndarray, ref: np.ndarray) -> None:
    np.testing.assert_allclose(out, ref, rtol=0, atol=TOL)
    assert float(np.abs(out - ref).mean()) <= MEAN_TOL


@pytest.fixture(params=["serial", "parallel"])
def rows(request, monkeypatch: pytest.MonkeyPatch) -> str:
    """Both ways the kernels run their rows: serially, or in parallel from any size (the threshold the
    confidence reads, numba_backend.LINEARISE_PARALLEL_MIN_PIXELS, patched)."""
    parallel = request.param == "parallel"
    monkeypatch.setattr(numba_backend, "LINEARISE_PARALLEL_MIN_PIXELS", 0 if parallel else 1 << 40)
    if parallel:
        assert numba_backend.threads() > 1 or numba.config.NUMBA_NUM_THREADS == 1
    return request.param


@pytest.mark.parametrize("shape", [(2, 2), (3, 7), (37, 53), (120, 160)])
@pytest.mark.parametrize("seed", [0, 1])
def test_random_inputs_match_the_reference(shape, seed, rows) -> None:
    rng = np.random.default_rng(seed)
    i0, i1 = (rng.random(shape, dtype=np.float32) for _ in range(2))
    flow = rng.normal(0.0, 4.0, shape + (2,)).astype(np.float32)  # many pixels leave the image
    ref = confidence(i0, i1, flow)
    out = confidence_numba(i0, i1, flow)
    assert out.dtype == np.float32 and out.shape == shape
    assert np.array_equal(out == 0, ref == 0)  # the same pixels leave the image
    assert_matches(out, ref)


def rendered_pair(kind: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An exactly rendered 160x120 motion scene (a pan with an object, an approach) and the realtime
    preset's flow of it: (i0, i1, flow (H, W, 2)) as the stream judges them (the photometric stage's pair)."""
    scene, _ = motion_scene(kind, (160, 120), np.random.default_rng(7), 0.2 if kind == "pan" else 0.0, objects=1)
    i0, i1, _ = render_grey_pair(scene)
    res = FlowEstimator(FlowConfig.preset("realtime")).estimate(i0, i1)
    return res.frames[0], res.frames[1], res.flow


@pytest.mark.parametrize("kind", ["pan", "approach"])
def test_rendered_pair_matches_the_reference(kind, rows) -> None:
    i0, i1, flow = rendered_pair(kind)
    ref = confidence(i0, i1, flow)
    assert 0.2 < ref.mean() < 0.99  # confident mostly, not everywhere
    assert_matches(confidence_numba(i0, i1, flow), ref)


def test_backends_and_stream_use_their_confidence() -> None:
    assert NUMPY.confidence is confidence and select_backend("numba").resolved().confidence is confidence_numba
    i0, i1, flow = rendered_pair("pan")
    est = FlowEstimator(FlowConfig.preset("realtime").replace(backend="numba"))
    assert_matches(est.confidence(i0, i1, flow), confidence(i0, i1, flow))
    for backend in ("numpy", "numba"):
        stream = FlowStream(StreamSettings(config=FlowConfig.preset("realtime").replace(backend=backend)))
        assert stream.process((255 * i0).astype(np.uint8), 0) is None
        out = stream.process((255 * i1).astype(np.uint8), 100_000_000)
        assert out.backend == backend
        conf = out.confidence()
        assert_matches(conf, confidence(*out.frames, out.flow))


# ------------------------------------------------------------------ the confidence at points only (the fits')
def border_and_grid(shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Every pixel of the first and last two rows and columns (the reflected box's border cases) and a
    regular grid inside, as (ys, xs) int arrays."""
    h, w = shape
    ys, xs = np.mgrid[0:h, 0:w]
    keep = (ys < 2) | (ys >= h - 2) | (xs < 2) | (xs >= w - 2) | ((ys % 5 == 2) & (xs % 7 == 3))
    return ys[keep], xs[keep]


@pytest.fixture(params=["boxes", "map"])
def at_path(request, monkeypatch: pytest.MonkeyPatch) -> str:
    """Both ways confidence_at_numba computes points: each point's box from its own terms, or the map near
    the points (numba_confidence.AT_MAP_COVER, the share of the image from which it takes the map, patched)."""
    monkeypatch.setattr(numba_confidence, "AT_MAP_COVER", math.inf if request.param == "boxes" else 0.0)
    return request.param


@pytest.mark.parametrize("shape", [(2, 2), (3, 7), (37, 53), (120, 160)])
def test_confidence_at_points_matches_the_map(shape, rows, at_path) -> None:
    rng = np.random.default_rng(3)
    i0, i1 = (rng.random(shape, dtype=np.float32) for _ in range(2))
    flow = rng.normal(0.0, 4.0, shape + (2,)).astype(np.float32)
    ys, xs = border_and_grid(shape)
    out = confidence_at_numba(i0, i1, flow, ys, xs)
    assert out.dtype == np.float32 and out.shape == ys.shape
    ref = confidence_at(i0, i1, flow, ys, xs)
    np.testing.assert_array_equal(ref, confidence(i0, i1, flow)[ys, xs])  # the reference is the map's
    assert np.array_equal(out == 0, ref == 0)
    assert_matches(out, ref)
    # against the numba map the only difference is the box's summation order: float32 rounding
    np.testing.assert_allclose(out, confidence_numba(i0, i1, flow)[ys, xs], rtol=0, atol=1e-5)
    grid = np.mgrid[0:shape[0], 0:shape[1]]  # any shape of points: here (H, W), every pixel
    np.testing.assert_allclose(confidence_at_numba(i0, i1, flow, *grid), confidence_numba(i0, i1, flow), atol=1e-5)


@pytest.mark.parametrize("kind", ["pan", "approach"])
def test_confidence_at_points_of_a_rendered_pair(kind, at_path) -> None:
    i0, i1, flow = rendered_pair(kind)
    ys, xs = border_and_grid(flow.shape[:2])
    assert_matches(confidence_at_numba(i0, i1, flow, ys, xs), confidence_at(i0, i1, flow, ys, xs))


@pytest.mark.parametrize("at", [confidence_at, confidence_at_numba])
def test_confidence_at_rejects_points_outside_or_not_integer(at) -> None:
    i0 = np.zeros((6, 8), np.float32)
    flow = np.zeros((6, 8, 2), np.float32)
    for ys, xs in (([6], [0]), ([0], [8]), ([-1], [0]), ([0, 1], [0]), (np.array([0.0]), np.array([1.0]))):
        with pytest.raises(InputError, match="confidence_at"):
            at(i0, i0, flow, np.asarray(ys), np.asarray(xs))


def test_backends_and_outputs_compute_points_alone() -> None:
    assert NUMPY.confidence_at is confidence_at
    assert select_backend("numba").resolved().confidence_at is confidence_at_numba
    i0, i1, _ = rendered_pair("pan")
    stream = FlowStream(StreamSettings(config=FlowConfig.preset("realtime").replace(backend="numba")))
    stream.process((255 * i0).astype(np.uint8), 0)
    out = stream.process((255 * i1).astype(np.uint8), 100_000_000)
    ys, xs = border_and_grid(out.flow.shape[:2])
    at = out.confidence_at(ys, xs)
    assert not out.confidence_computed  # the points alone, not the map
    assert_matches(at, confidence_at(*out.frames, out.flow, ys, xs))
    np.testing.assert_array_equal(out.confidence_at(ys, xs), at)
    np.testing.assert_array_equal(FlowEstimator(FlowConfig.preset("realtime").replace(backend="numba"))
                                  .confidence_at(*out.frames, out.flow, ys, xs), at)
    conf = out.confidence()
    np.testing.assert_array_equal(out.confidence_at(ys, xs), conf[ys, xs])  # once computed: read from the map


# ------------------------------------------------------------- the confidence where a mask is True (the mask's)
def specks_and_borders(shape: tuple[int, int], seed: int) -> np.ndarray:
    """A bool (H, W): random specks and a block, and the first and last rows and columns in places."""
    rng = np.random.default_rng(seed)
    where = rng.random(shape) < 0.03
    h, w = shape
    where[h // 3:h // 2 + 1, w // 4:w // 2 + 1] = True
    where[0, : w // 2] = where[-1, w // 3:] = where[:, 0] = where[h // 2:, -1] = True
    return where


@pytest.mark.parametrize("shape", [(2, 2), (3, 7), (37, 53), (120, 160)])
def test_confidence_where_matches_the_map_there(shape, rows) -> None:
    rng = np.random.default_rng(5)
    i0, i1 = (rng.random(shape, dtype=np.float32) for _ in range(2))
    flow = rng.normal(0.0, 4.0, shape + (2,)).astype(np.float32)
    full = confidence(i0, i1, flow)
    middle = np.zeros(shape, bool)  # rows away from the borders: the box filter runs on a band of rows
    middle[shape[0] // 3:shape[0] // 2 + 1, shape[1] // 4:] = True
    for where in (specks_and_borders(shape, 2), middle):
        ref = confidence(i0, i1, flow, where)
        np.testing.assert_array_equal(ref, np.where(where, full, 0.0))  # the reference: the map, cleared elsewhere
        out = confidence_numba(i0, i1, flow, where)
        assert out.dtype == np.float32 and out.shape == shape and not out[~where].any()
        assert_matches(out, ref)
        # against the numba map: the terms beyond the box's reach of ``where`` are 0 instead, nothing else
        np.testing.assert_allclose(out, np.where(where, confidence_numba(i0, i1, flow), 0.0), rtol=0, atol=1e-6)
    np.testing.assert_array_equal(confidence_numba(i0, i1, flow, np.ones(shape, bool)), confidence_numba(i0, i1, flow))
    assert not confidence_numba(i0, i1, flow, np.zeros(shape, bool)).any()


def test_confidence_where_of_a_rendered_pair_and_its_wiring() -> None:
    i0, i1, flow = rendered_pair("pan")
    where = specks_and_borders(flow.shape[:2], 3)
    est = FlowEstimator(FlowConfig.preset("realtime").replace(backend="numba"))
    assert_matches(est.confidence(i0, i1, flow, where), confidence(i0, i1, flow, where))
    stream = FlowStream(StreamSettings(config=FlowConfig.preset("realtime").replace(backend="numba")))
    stream.process((255 * i0).astype(np.uint8), 0)
    out = stream.process((255 * i1).astype(np.uint8), 100_000_000)
    part = out.confidence_in(where)
    assert not out.confidence_computed and not part[~where].any()  # those pixels alone, not the map
    assert_matches(part, confidence(*out.frames, out.flow, where))
    conf = out.confidence()
    assert out.confidence_in(where) is conf  # once computed: the map


@pytest.mark.parametrize("conf", [confidence, confidence_numba])
def test_confidence_rejects_a_where_of_another_shape_or_type(conf) -> None:
    i0 = np.zeros((6, 8), np.float32)
    flow = np.zeros((6, 8, 2), np.float32)
    for where in (np.ones((6, 7), bool), np.ones((6, 8), np.uint8)):
        with pytest.raises(InputError, match="where"):
            conf(i0, i0, flow, where)


# ------------------------------------------- what the calls on one pair share: frame 1's planes (confidence.Shared)
@pytest.fixture
def planes_calls(monkeypatch: pytest.MonkeyPatch) -> list[tuple[int, ...]]:
    """The shapes of the planes numba_confidence computes, one entry per computation (planes_kernel wrapped)."""
    calls: list[tuple[int, ...]] = []
    kernel = numba_confidence.planes_kernel
    monkeypatch.setattr(numba_confidence, "planes_kernel", lambda out, img: calls.append(img.shape) or kernel(out, img))
    return calls


@pytest.mark.parametrize("shape", [(3, 7), (37, 53), (120, 160)])
def test_shared_planes_give_the_same_bits_computed_once(shape, rows, planes_calls) -> None:
    rng = np.random.default_rng(9)
    i0, i1, j0, j1 = (rng.random(shape, dtype=np.float32) for _ in range(4))
    flow = rng.normal(0.0, 4.0, shape + (2,)).astype(np.float32)
    ys, xs = np.mgrid[1:shape[0]:3, 0:shape[1]:3]  # dense: the map near the points (AT_MAP_COVER)
    assert ys.size * 25 >= numba_confidence.AT_MAP_COVER * i0.size
    points = np.zeros(shape, bool)
    points[ys, xs] = True
    where = specks_and_borders(shape, 4)
    alone_at, alone_in = confidence_at_numba(i0, i1, flow, ys, xs), confidence_numba(i0, i1, flow, where)
    # the points' ratio alone: confidence_numba's with ``where`` the points, bit for bit
    np.testing.assert_array_equal(alone_at, confidence_numba(i0, i1, flow, points)[ys, xs])
    del planes_calls[:]
    shared: dict[str, np.ndarray] = {}
    np.testing.assert_array_equal(confidence_at_numba(i0, i1, flow, ys, xs, shared=shared), alone_at)
    assert list(shared) == ["numba.planes1"] and len(planes_calls) == 1
    confidence_numba(j0, j1, flow)  # another pair between the calls: the thread's scratch, not the kept planes
    np.testing.assert_array_equal(confidence_numba(i0, i1, flow, where, shared=shared), alone_in)
    np.testing.assert_array_equal(confidence_numba(i0, i1, flow, shared=shared), confidence_numba(i0, i1, flow))
    assert len(planes_calls) == 3  # the pair's planes once, the other pair's twice (nothing shared there)
    ref: dict[str, np.ndarray] = {}  # the reference keeps both frames' planes, the same values
    np.testing.assert_array_equal(confidence_at(i0, i1, flow, ys, xs, shared=ref), confidence_at(i0, i1, flow, ys, xs))
    np.testing.assert_array_equal(confidence(i0, i1, flow, where, shared=ref), confidence(i0, i1, flow, where))
    assert sorted(ref) == ["numpy.planes0", "numpy.planes1"]


def test_outputs_share_the_planes_between_the_fits_and_the_mask(planes_calls) -> None:
    from flow_node.pipeline.derived import MotionAnalysis
    from flow_node.pipeline.motion import moving_mask

    i0, i1, _ = rendered_pair("pan")
    settings = StreamSettings(config=FlowConfig.preset("realtime").replace(backend="numba"))
    stream = FlowStream(settings)
    stream.process((255 * i0).astype(np.uint8), 0)
    out = stream.process((255 * i1).astype(np.uint8), 100_000_000)
    del planes_calls[:]
    a = MotionAnalysis.of(out)
    mask = a.moving_mask
    assert mask.any() and not out.confidence_computed and len(planes_calls) == 1  # the fits' and the mask's
    est = FlowEstimator(settings.config)  # each call on its own: the same mask, bit for bit
    alone = moving_mask(out.flow, lambda where: est.confidence(*out.frames, out.flow, where), a.dominant)
    np.testing.assert_array_equal(mask, alone)
    assert a.dominant == MotionAnalysis(out.flow, lambda: est.confidence(*out.frames, out.flow), 0.1,
                                        confidence_at=lambda ys, xs: est.confidence_at(*out.frames, out.flow, ys, xs),
                                        fits=a.fits).dominant
    del planes_calls[:]
    conf = out.confidence()  # the map after them: from the kept planes too (then let go), the same bits
    assert not planes_calls and out.confidence_computed
    np.testing.assert_array_equal(conf, est.confidence(*out.frames, out.flow))
