"""Colour input for the census data term (core/colour.py; the form: census.census_form, numba:
numba_census.census_form_numba, with C channels): the colour form against the grey one, the numba kernels
against the numpy oracle, and the engine, the stream and the
CLI with ``colour = channels`` -- invariant to white balance, and seeing edges that luma does not."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import small_frames
from synth import constant_flow, interior, isoluminant_pair, pair_from_flow, texture

from flow_node.cli.estimate import read_planes
from flow_node.core import photometric
from flow_node.core.api import FlowEstimator, to_grey, to_planes
from flow_node.core.backends import NUMPY
from flow_node.core.census import CENSUS, census_form, level_signature, warped_frames
from flow_node.core.census_noise import channel_noise, pair_noise
from flow_node.core.colour import channel_maps, normalise_channel_pair, normalised_channels
from flow_node.core.engine import solve_pair
from flow_node.core.errors import InputError
from flow_node.core.metrics import aee
from flow_node.core.numba_backend import WARPER
from flow_node.core.numba_census import census_form_numba, level_signature_numba
from flow_node.core.numba_sort import sorted_sample_numba
from flow_node.core.pyramid import build_pyramid, channel_pyramid, pyramid_shapes
from flow_node.core.warping import NUMPY_WARPER, Sample
from flow_node.pipeline.stream import FlowStream, StreamSettings

H, W = 36, 48
AGREE = 1e-5
CENSUS_CFG = small_frames.CONFIG.with_overrides(["photometric=census"])
COLOUR_CFG = CENSUS_CFG.with_overrides(["colour=channels"])


def channels(seed: int, n: int = 3, h: int = H, w: int = W) -> np.ndarray:
    return np.stack([texture(h, w, seed=seed + k, cell=2).image for k in range(n)]).astype(np.float32)


def warp_of(c1: np.ndarray, seed: int, sample: Sample = NUMPY_WARPER.sample) -> tuple[np.ndarray, ...]:
    """A flow v0 that takes a corner of the frame outside, c1's (C, H, W) interpolation coefficients and c1
    warped by v0 with its outside mask (census.warped_frames)."""
    v0 = (0.5 * np.random.default_rng(seed).standard_normal((2, H, W))).astype(np.float32)
    v0[0, :4, :5] = -20.0
    coefs = NUMPY_WARPER.coefficients(c1, "bspline")
    return (v0, coefs, *warped_frames(coefs, c1, v0, "bspline", sample))


def test_three_equal_channels_give_the_grey_census_form() -> None:
    grey, i1 = channels(1, n=1)[0], channels(7, n=1)
    v0, coefs, _, outside = warp_of(np.concatenate([i1] * 3), 2)
    assert outside[:4, :5].all() and not outside[4:-4, 6:-4].any()
    f0, g0 = level_signature(grey, CENSUS)
    cf0, cg0 = level_signature(np.stack([grey] * 3), CENSUS)
    for robust in (False, True):
        want = census_form(f0, g0, coefs[:1], i1, v0, "bspline", robust, CENSUS)
        got = census_form(cf0, cg0, coefs, np.concatenate([i1] * 3), v0, "bspline", robust, CENSUS)
        np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-5)


def test_a_channel_with_different_texture_changes_the_form() -> None:
    i0, i1 = channels(1), channels(11)
    v0, coefs, _, _ = warp_of(i1, 3)
    base = census_form(*level_signature(i0, CENSUS), coefs, i1, v0, "bspline", False, CENSUS)
    i0b = i0.copy()
    i0b[2] = channels(21, n=1)[0]
    other = census_form(*level_signature(i0b, CENSUS), coefs, i1, v0, "bspline", False, CENSUS)
    assert np.abs(other - base).max() > 1e-2


@pytest.mark.parametrize("radius", [1, 2])
@pytest.mark.parametrize("robust", [False, True])
def test_numba_colour_form_matches_numpy(robust: bool, radius: int) -> None:
    params = replace(CENSUS, radius=radius)
    i0, i1 = channels(4), channels(14)
    v0, coefs, warped, outside = warp_of(i1, 5)
    f0, g0 = level_signature(i0, params)
    want = census_form(f0, g0, coefs, i1, v0, "bspline", robust, params)
    _, _, warped_n, outside_n = warp_of(i1, 5, WARPER.sample)
    np.testing.assert_allclose(warped_n, warped, atol=AGREE)
    np.testing.assert_array_equal(outside_n, outside)
    f0n, g0n = level_signature_numba(i0, params)
    assert g0n is None
    np.testing.assert_allclose(f0n, f0, atol=AGREE)
    got = census_form_numba(f0n, None, WARPER.coefficients(i1, "bspline"), i1, v0, "bspline", robust, params)
    np.testing.assert_allclose(got, want, atol=AGREE, rtol=AGREE)
    assert np.all(got[:, :4, :5] == 0.0) and np.all(got[2, 4:-4, 6:-4] > 0.0)  # no data term only outside


def test_normalise_channel_pair_undoes_a_gain_per_channel() -> None:
    frame = channels(6)
    balanced = frame * np.array([1.15, 1.0, 0.8], np.float32)[:, None, None]
    np.testing.assert_allclose(normalise_channel_pair(balanced, balanced)[1], normalise_channel_pair(frame, frame)[1],
                               atol=1e-5)


def test_each_channel_is_sampled_and_mapped_once_per_pair(monkeypatch: pytest.MonkeyPatch) -> None:
    """The colour path takes each channel's sorted samples and maps once (colour.channel_maps, the backend's sample)
    and both the normalisation and the noise floor use them: a pair with colour channels sorts and maps 2 frames
    of luma and 2 x 3 channel frames, no more (before task photoapi the noise floor took the channels' again)."""
    sorted_by: list[int] = []
    mapped: list[int] = []
    frame_map, sort = photometric.frame_map, photometric.sorted_sample
    monkeypatch.setattr(photometric, "frame_map", lambda s: mapped.append(s.size) or frame_map(s))
    backend = NUMPY._replace(sample=lambda img: sorted_by.append(img.size) or sort(img))
    monkeypatch.setattr(photometric, "sorted_sample", lambda img: pytest.fail("the numpy sort, not the backend's"))
    c0, c1 = channels(3), channels(5)
    grey = [c.mean(axis=0).astype(np.float32) for c in (c0, c1)]
    cfg = COLOUR_CFG.replace(census_presmooth=0.45, census_noise_k=3.0)
    _, _, judged = solve_pair(grey[0], grey[1], cfg, backend, channels=(c0, c1))
    assert len(sorted_by) == 8 and len(mapped) == 8
    assert judged.noise is not None and judged.noise.blur == 0.45


def test_the_shared_channel_maps_give_what_each_step_took_on_its_own() -> None:
    """colour.normalised_channels (maps taken once, by the numba backend's sort) gives the normalised channels and,
    through census_noise.channel_noise, the noise that the normalisation and a per-channel pair_noise give with maps
    of their own (numpy's sort), bit for bit; with a presmooth and with coarse (blurred) channels."""
    rng = np.random.default_rng(4)
    for c0, c1, gain, presmooth in ((channels(3), channels(5), 0.8, 0.45),
                                    (np.rint(channels(3) * 20) / 255, np.rint(channels(5) * 20) / 255, 1.0, 0.0)):
        c0, c1 = c0.astype(np.float32), (c1 + 0.01 * rng.standard_normal(c1.shape)).astype(np.float32)
        shared = normalised_channels(c0, c1, gain, presmooth, sorted_sample_numba)
        own = tuple(photometric.frame_maps(photometric.frame_samples(a, b), gain, presmooth=presmooth)
                    for a, b in zip(c0, c1, strict=True))
        assert shared.maps == own and all(m[1] > 0 for m in own)
        for k in (0, 1):
            np.testing.assert_array_equal(shared.normalised[k], normalise_channel_pair(c0, c1, gain, own)[k])
        built = channel_maps(c0, c1, gain, presmooth)  # the numpy sort: the same maps
        np.testing.assert_array_equal(shared.normalised[1], normalise_channel_pair(c0, c1, gain, built)[1])
        noises = [pair_noise((a, b), m, gain, (na, nb))
                  for a, b, m, na, nb in zip(c0, c1, own, *shared.normalised, strict=True)]
        noise = channel_noise((c0, c1), shared.maps, gain, shared.normalised)
        assert (noise.sigma, noise.blur) == (max(n.sigma for n in noises), max(n.blur for n in noises))


def rgb_pair(seed: int, u: float = 1.5, v: float = -0.75, h: int = 60, w: int = 80
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An RGB pair (H, W, 3) float32 of three independent textures moving by (u, v), and its flow."""
    gt = constant_flow(h, w, u, v)
    planes = [pair_from_flow(texture(h, w, seed=seed + k), gt) for k in range(3)]
    return (np.stack([p[0] for p in planes], -1).astype(np.float32),
            np.stack([p[1] for p in planes], -1).astype(np.float32), gt)


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_colour_flow_is_invariant_to_white_balance(backend: str) -> None:
    c0, c1, gt = rgb_pair(30)
    cfg = COLOUR_CFG.with_overrides([f"backend={backend}"])
    est = FlowEstimator(cfg)
    plain = est.estimate(c0, c1).flow
    balanced = est.estimate(c0, c1 * np.array([1.2, 1.0, 0.8], np.float32)).flow
    assert aee(interior(plain), interior(gt)) < 0.1
    np.testing.assert_allclose(balanced, plain, atol=1e-3)


def test_colour_sees_motion_that_luma_does_not() -> None:
    c0, c1, gt = isoluminant_pair(40)
    assert np.ptp(to_grey(c0)) < 1e-5
    grey = FlowEstimator(CENSUS_CFG).estimate(c0, c1).flow
    colour = FlowEstimator(COLOUR_CFG).estimate(c0, c1).flow
    assert aee(interior(grey), interior(gt)) > 1.0  # luma is flat: no motion to see
    assert aee(interior(colour), interior(gt)) < 0.15


def test_grey_input_and_grey_value_terms_ignore_the_colour_setting() -> None:
    c0, c1, _ = rgb_pair(50)
    grey0, grey1 = to_grey(c0), to_grey(c1)
    np.testing.assert_array_equal(FlowEstimator(COLOUR_CFG).estimate(grey0, grey1).flow,
                                  FlowEstimator(CENSUS_CFG).estimate(grey0, grey1).flow)
    normalise = small_frames.CONFIG.replace(photometric="normalise")
    np.testing.assert_array_equal(FlowEstimator(normalise.with_overrides(["colour=channels"])).estimate(c0, c1).flow,
                                  FlowEstimator(normalise).estimate(c0, c1).flow)


def test_to_planes_orders_channels_and_keeps_grey_grey() -> None:
    rgb = (np.arange(4 * 5 * 3).reshape(4, 5, 3) % 256).astype(np.uint8)
    grey, planes = to_planes(rgb)
    np.testing.assert_array_equal(grey, to_grey(rgb))
    np.testing.assert_allclose(planes, np.moveaxis(rgb, -1, 0) / np.float32(255.0), rtol=1e-6)
    _, bgr = to_planes(rgb[..., ::-1], channel_order="bgr")
    np.testing.assert_array_equal(bgr, planes)
    _, rgba = to_planes(np.dstack([rgb, rgb[..., :1]]))
    np.testing.assert_array_equal(rgba, planes)
    assert to_planes(rgb[..., 0])[1] is None
    with pytest.raises(InputError, match="dtype"):
        to_planes(rgb.astype(np.int32))


def test_mismatched_planes_are_rejected() -> None:
    c0, c1, _ = rgb_pair(60)
    (i0, p0), (i1, p1) = to_planes(c0), to_planes(c1)
    with pytest.raises(InputError, match="colour planes"):
        FlowEstimator(COLOUR_CFG).estimate_grey(i0, i1, channels=(p0, p1[:, :-1]))


@pytest.mark.parametrize("scale", [1.0, 0.5])
def test_stream_uses_colour_planes(scale: float) -> None:
    c0, c1, gt = isoluminant_pair(70)
    u8 = [(c * 255).round().astype(np.uint8) for c in (c0, c1)]
    errors = []
    for cfg in (COLOUR_CFG, CENSUS_CFG):
        s = FlowStream(StreamSettings(config=cfg, input_scale=scale))
        s.process(u8[0], 0, "rgb8")
        out = s.process(u8[1], 1, "rgb8")
        h, w = out.flow.shape[:2]
        errors.append(aee(interior(out.flow, 4), interior(constant_flow(h, w, gt[0, 0, 0] * scale, gt[0, 0, 1] * scale),
                                                          4)))
    # the luma cannot see the isoluminant texture (1.5 / 0.72 px); the planes can (0.024 / 0.17 px: at 0.5 the
    # frames are 40 x 30 px, where realtime's one finest census warp leaves more than its two warps did, 0.07)
    assert errors[1] > 0.3 * scale and errors[0] < 0.35 * errors[1], errors


def test_cli_reads_colour_planes(tmp_path: pytest.TempPathFactory) -> None:
    import cv2

    c0 = np.clip(rgb_pair(80)[0], 0.0, 1.0)
    path = tmp_path / "f.png"
    cv2.imwrite(str(path), (c0[..., ::-1] * 255).round().astype(np.uint8))  # OpenCV writes BGR
    grey, planes = read_planes(str(path))
    assert planes is not None and planes.shape == (3, 60, 80)
    np.testing.assert_allclose(planes, np.moveaxis(c0, -1, 0), atol=0.6 / 255)
    assert read_planes(str(path), colour=False)[1] is None and grey.shape == (60, 80)


@pytest.mark.parametrize("antialias", [0, 6])
def test_channel_pyramid_is_each_channels_pyramid(antialias: int) -> None:
    frame = channels(9, h=97, w=131)
    shapes = pyramid_shapes((97, 131), 6, 0.5, 8)
    levels = channel_pyramid(frame, shapes, 0.5, antialias)
    assert [lv.shape for lv in levels] == [(3,) + s for s in shapes]
    for k in range(3):
        for got, want in zip(levels, build_pyramid(frame[k], shapes, 0.5, antialias), strict=True):
            np.testing.assert_allclose(got[k], want, atol=1e-6)
