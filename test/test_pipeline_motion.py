"""The derived motion outputs (flow_node.pipeline.motion / expansion / derived) on exact flow fields built
analytically, plus one rendered pair through the realtime engine. Signs are asserted as well as sizes:
a rotation from +x towards +y is positive, an expanding image has scale > 1, divergence > 0 and a finite
time to contact, a contracting one does not."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flow_node.core import FlowConfig, FlowEstimator
from flow_node.core.confidence import confidence as flow_confidence
from flow_node.core.errors import ConfigError, InputError
from flow_node.pipeline.derived import MotionAnalysis, MotionSettings
from flow_node.pipeline.expansion import divergence, focus_of_expansion, region_ttc
from flow_node.pipeline.motion import MaskThreshold, MotionDetector, dominant_motion, moving_fraction, moving_mask

H, W = 120, 160
CENTRE = np.array([(W - 1) / 2.0, (H - 1) / 2.0])


def grid() -> np.ndarray:
    ys, xs = np.mgrid[0:H, 0:W].astype(np.float64)
    return np.stack([xs, ys], axis=-1)


def similarity_flow(tx: float, ty: float, deg: float, scale: float, centre: np.ndarray = CENTRE) -> np.ndarray:
    """x -> centre + scale R(deg) (x - centre) + t, as a flow (H, W, 2) float32."""
    a = math.radians(deg)
    m = scale * np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    p = grid()
    return (centre + (p - centre) @ m.T + np.array([tx, ty]) - p).astype(np.float32)


def homography_flow(hm: np.ndarray) -> np.ndarray:
    p = grid()
    den = hm[2, 0] * p[..., 0] + hm[2, 1] * p[..., 1] + hm[2, 2]
    x = (hm[0, 0] * p[..., 0] + hm[0, 1] * p[..., 1] + hm[0, 2]) / den
    y = (hm[1, 0] * p[..., 0] + hm[1, 1] * p[..., 1] + hm[1, 2]) / den
    return np.stack([x, y], axis=-1).astype(np.float32) - p.astype(np.float32)


ONES = np.ones((H, W), np.float32)
BLOCK = (slice(20, 70), slice(30, 90))  # 50 x 60 px = 15.6 % of the frame


def with_block(flow: np.ndarray, delta: tuple[float, float] = (2.0, -1.5)) -> np.ndarray:
    out = flow.copy()
    out[BLOCK] += np.array(delta, np.float32)
    return out


# ------------------------------------------------------------------------------------------ dominant motion
@pytest.mark.parametrize("tx, ty, deg, scale", [(1.3, -0.6, 0.0, 1.0), (0.0, 0.0, 1.5, 1.0),
                                                (0.4, 0.2, -2.0, 1.02), (-0.8, 1.1, 0.7, 0.985)])
def test_dominant_motion_despite_a_moving_block(tx: float, ty: float, deg: float, scale: float) -> None:
    m = dominant_motion(with_block(similarity_flow(tx, ty, deg, scale)), ONES)
    assert m is not None
    assert abs(m.tx - tx) < 1e-5 and abs(m.ty - ty) < 1e-5
    assert abs(m.rotation_deg - deg) < 1e-5 and abs(m.scale - scale) < 1e-7
    assert m.inlier_share == pytest.approx(1.0 - 0.156, abs=0.02)  # the block is the outlier share
    assert m.center == (CENTRE[0], CENTRE[1])


def test_rotation_sign_and_scale_direction() -> None:
    # a point right of the centre moving down (+y) is a positive rotation (clockwise on screen)
    m = dominant_motion(similarity_flow(0.0, 0.0, 1.0, 1.0), ONES)
    assert m is not None and m.rotation_deg > 0.9
    flow = similarity_flow(0.0, 0.0, 0.0, 1.0)
    flow[..., 1] += ((grid()[..., 0] - CENTRE[0]) * 0.02).astype(np.float32)  # v grows to the right
    m = dominant_motion(flow, ONES)
    assert m is not None and m.rotation_deg > 0.5
    zoom_in, zoom_out = (dominant_motion(similarity_flow(0, 0, 0, s), ONES) for s in (1.03, 0.97))
    assert zoom_in is not None and zoom_in.scale > 1.02 and zoom_in.ttc_frames == pytest.approx(1 / 0.03)
    assert zoom_out is not None and zoom_out.scale < 0.98 and zoom_out.ttc_frames == math.inf


def test_homography_of_a_perspective_flow_and_its_prediction() -> None:
    hm = np.array([[1.01, 0.015, 2.0], [-0.01, 0.995, -1.5], [6e-5, -4e-5, 1.0]])
    flow = homography_flow(hm)
    m = dominant_motion(with_block(flow, (3.0, 1.0)), ONES)
    assert m is not None
    assert np.allclose(np.array(m.homography), hm, rtol=0, atol=[[1e-6, 1e-6, 1e-4]] * 2 + [[1e-9, 1e-9, 0]])
    assert np.max(np.abs(m.predicted_flow((H, W)) - flow)) < 1e-3
    assert m.inlier_share == pytest.approx(1.0 - 0.156, abs=0.02)


def test_confidence_zero_hides_garbage_and_none_without_support() -> None:
    flow = with_block(similarity_flow(0.5, 0.25, 0.5, 1.0), (40.0, -80.0))
    conf = ONES.copy()
    conf[BLOCK] = 0.0
    m = dominant_motion(flow, conf)
    assert m is not None and abs(m.tx - 0.5) < 1e-6 and m.inlier_share == pytest.approx(1.0)
    assert dominant_motion(flow, np.zeros_like(conf)) is None
    assert not moving_mask(flow, conf, None).any()
    with pytest.raises(InputError):
        dominant_motion(flow, conf[:, :-1])


# ------------------------------------------------------------------------------------------- moving pixels
def test_moving_mask_is_the_block_and_empty_for_camera_motion() -> None:
    base = similarity_flow(1.0, -0.5, 1.2, 1.01)
    flow = with_block(base)
    m = dominant_motion(flow, ONES)
    mask = moving_mask(flow, ONES, m)
    assert mask.dtype == np.uint8 and set(np.unique(mask)) == {0, 255}
    truth = np.zeros((H, W), bool)
    truth[BLOCK] = True
    assert not np.any((mask > 0) & ~truth)  # the elliptic opening only rounds the block's 4 corners
    assert np.sum(truth & (mask == 0)) <= 4 * 3 and mask[BLOCK][2:-2, 2:-2].all()
    assert moving_fraction(mask) == pytest.approx(truth.mean(), abs=1e-3)
    assert not moving_mask(base, ONES, dominant_motion(base, ONES)).any()  # static scene: nothing moves


def test_moving_mask_threshold_confidence_and_opening() -> None:
    base = similarity_flow(0.0, 0.0, 0.0, 1.0)
    m = dominant_motion(base, ONES)
    small = with_block(base, (0.4, 0.0))  # below abs_px 0.5
    assert not moving_mask(small, ONES, m).any()
    assert moving_mask(small, ONES, m, MaskThreshold(abs_px=0.3)).any()
    conf = ONES.copy()
    conf[20:70, 30:60] = 0.1  # the left half of the block is not trusted
    mask = moving_mask(with_block(base), conf, m)
    assert not mask[20:70, 30:60].any() and mask[25:65, 62:88].all()
    speck = base.copy()
    speck[100:103, 10:13] += 5.0  # 3x3 px: narrower than the 5x5 opening
    assert not moving_mask(speck, ONES, m).any()
    assert moving_mask(speck, ONES, m, MaskThreshold(opening_px=0)).sum() == 9 * 255
    with pytest.raises(ConfigError):
        MaskThreshold(abs_px=0.0)


def test_detector_hysteresis() -> None:
    det = MotionDetector(area_fraction=0.05, on_frames=3, off_frames=2)
    seq = [0.1, 0.1, 0.0, 0.1, 0.1, 0.1, 0.0, 0.1, 0.0, 0.0, 0.1]
    states = [det.update(f) for f in seq]
    assert states == [False, False, False, False, False, True, True, True, True, False, False]
    det.reset()
    assert not det.detected and not det.update(1.0)
    with pytest.raises(ConfigError):
        MotionDetector(area_fraction=0.0)


# ------------------------------------------------------------------------ divergence, TTC, focus of expansion
def test_divergence_of_a_zoom() -> None:
    expand = divergence(similarity_flow(0, 0, 0, 1.02, np.array([50.0, 40.0])))
    assert expand.dtype == np.float32 and expand.shape == (H, W)
    assert np.allclose(expand[1:-1, 1:-1], 0.04, atol=1e-5)  # 2 (s - 1)
    assert np.allclose(divergence(similarity_flow(0, 0, 0, 0.98))[1:-1, 1:-1], -0.04, atol=1e-5)
    assert np.allclose(divergence(similarity_flow(1.0, 2.0, 0, 1.0)), 0.0, atol=1e-6)


@pytest.mark.parametrize("tau", [10.0, 40.0, 200.0])
def test_region_ttc_of_an_approaching_plane(tau: float) -> None:
    foe = np.array([60.0, 70.0])
    flow = with_block(similarity_flow(0, 0, 1.0, 1.0 + 1.0 / tau, foe))  # a rotation does not change it
    ttc = region_ttc(flow, ONES, interval_s=0.05)
    assert (ttc.rows, ttc.cols, len(ttc.regions)) == (3, 3, 9)
    assert np.allclose(ttc.grid(), tau, rtol=1e-4)
    assert np.allclose(ttc.grid("ttc_seconds"), tau * 0.05, rtol=1e-4)
    assert ttc.centre.row == 1 and ttc.centre.col == 1 and ttc.centre.divergence > 0
    assert ttc.regions[0].bounds == (0, 0, 53, 40) and ttc.regions[-1].bounds == (107, 80, 160, 120)


def test_region_ttc_receding_static_and_unsupported() -> None:
    assert np.all(region_ttc(similarity_flow(0, 0, 0, 0.98), ONES).grid() == math.inf)  # contracting
    assert np.all(region_ttc(similarity_flow(1.0, -1.0, 2.0, 1.0), ONES).grid() == math.inf)  # pan + rotation
    conf = ONES.copy()
    conf[:40, :53] = 0.0
    ttc = region_ttc(similarity_flow(0, 0, 0, 1.05), conf)
    assert math.isnan(ttc.grid()[0, 0]) and ttc.regions[0].support == 0.0
    assert ttc.regions[0].ttc_seconds is None and ttc.grid()[2, 2] == pytest.approx(20.0)


def test_focus_of_expansion() -> None:
    foe = np.array([50.0, 80.0])
    f = focus_of_expansion(similarity_flow(0, 0, 0, 1.03, foe), ONES)
    assert f is not None and f.expanding and abs(f.x - 50.0) < 1e-4 and abs(f.y - 80.0) < 1e-4
    g = focus_of_expansion(similarity_flow(0, 0, 0, 0.97, foe), ONES)
    assert g is not None and not g.expanding and abs(g.x - 50.0) < 1e-4
    assert focus_of_expansion(similarity_flow(2.0, 1.0, 0, 1.0), ONES) is None  # a pan: at infinity
    assert focus_of_expansion(np.zeros((H, W, 2), np.float32), ONES) is None


# --------------------------------------------------------------------------------------------- the bundle
def test_motion_analysis_bundle() -> None:
    flow = with_block(similarity_flow(0.0, 0.0, 0.0, 1.0 + 1 / 30, np.array([70.0, 50.0])))
    a = MotionAnalysis(flow, ONES, interval_s=0.1)
    assert a.moving_fraction == pytest.approx(0.156, abs=0.01)
    s = a.summary()
    assert s["ttc_centre_frames"] == pytest.approx(30.0, rel=1e-4)
    assert s["ttc_centre_seconds"] == pytest.approx(3.0, rel=1e-4)
    assert s["foe"]["expanding"] and s["dominant"]["scale"] > 1.0
    assert MotionAnalysis(flow, ONES, interval_s=0.0).ttc.centre.ttc_seconds is None
    assert a.divergence is a.divergence  # cached
    with pytest.raises(ConfigError):
        MotionSettings(grid_rows=0)


# ------------------------------------------------------------------------- a rendered pair through the engine
def test_rendered_pairs_through_realtime() -> None:
    from flow_node.bag.motion_scenes import motion_scene
    from flow_node.bag.scenes import render_grey_pair

    est = FlowEstimator(FlowConfig.preset("realtime"))
    scene, truth = motion_scene("rotation", (256, 192), np.random.default_rng(7), object_share=0.25)
    i0, i1, gt = render_grey_pair(scene)
    res = est.estimate(i0.astype(np.float32), i1.astype(np.float32))
    a = MotionAnalysis(res.flow, flow_confidence(*res.frames, res.flow))
    d = a.dominant
    assert d is not None
    assert math.hypot(d.tx - truth.tx, d.ty - truth.ty) < 0.05
    assert abs(d.rotation_deg - truth.rotation_deg) < 0.05 and abs(truth.rotation_deg) > 0.4
    objects = scene.layer_map(0) > 0
    mask = a.moving_mask > 0
    assert 0.2 < objects.mean() < 0.3
    assert np.sum(mask & objects) / np.sum(mask | objects) > 0.8

    scene, truth = motion_scene("approach", (256, 192), np.random.default_rng(8))
    i0, i1, _ = render_grey_pair(scene)
    res = est.estimate(i0.astype(np.float32), i1.astype(np.float32))
    a = MotionAnalysis(res.flow, flow_confidence(*res.frames, res.flow))
    assert truth.ttc_frames is not None and 10 <= truth.ttc_frames <= 200
    assert np.nanmedian(np.abs(a.ttc.grid() / truth.ttc_frames - 1.0)) < 0.15
    assert a.moving_fraction < 0.01


# ------------------------------------------------------- the fits with the confidence at their samples alone
def test_fits_take_the_confidence_at_their_samples_alone() -> None:
    from flow_node.bag.motion_scenes import motion_scene
    from flow_node.bag.scenes import render_grey_pair
    from flow_node.pipeline.stream import FlowStream, StreamSettings

    scene, _ = motion_scene("rotation", (256, 192), np.random.default_rng(7), object_share=0.25)
    i0, i1, _ = render_grey_pair(scene)
    stream = FlowStream(StreamSettings(config=FlowConfig.preset("realtime")))
    stream.process((255 * i0).astype(np.uint8), 0)
    out = stream.process((255 * i1).astype(np.uint8), 100_000_000)
    a = MotionAnalysis.of(out)
    d, ttc, foe = a.dominant, a.ttc, a.foe
    assert d is not None and not out.confidence_computed  # the fits read the points, not the map
    ref = MotionAnalysis(out.flow, out.confidence(), 0.1)  # the map given: the fits read it
    assert ref.dominant is not None
    assert abs(d.tx - ref.dominant.tx) < 1e-4 and abs(d.rotation_deg - ref.dominant.rotation_deg) < 1e-4
    assert abs(d.inlier_share - ref.dominant.inlier_share) < 1e-4
    np.testing.assert_allclose(ttc.grid("expansion"), ref.ttc.grid("expansion"), rtol=0, atol=1e-6)
    assert (foe is None) == (ref.foe is None)
    np.testing.assert_array_equal(a.moving_mask, ref.moving_mask)  # the mask: the whole map (now computed)
    # the weights as a function of the points read from the map: the very same fits
    conf = out.confidence()
    at = lambda ys, xs: conf[ys, xs]  # noqa: E731
    assert dominant_motion(out.flow, at) == dominant_motion(out.flow, conf)
    for field in ("expansion", "divergence", "ttc_frames", "support"):  # NaN where unsupported: array_equal
        np.testing.assert_array_equal(region_ttc(out.flow, at).grid(field), region_ttc(out.flow, conf).grid(field))
    assert focus_of_expansion(out.flow, at) == focus_of_expansion(out.flow, conf)
    # the mask needs the whole map: computed first, the dominant motion reads it (no points computed besides)
    calls: list[int] = []
    b = MotionAnalysis(out.flow, out.confidence, 0.1, confidence_at=lambda ys, xs: calls.append(ys.size) or at(ys, xs))
    np.testing.assert_array_equal(b.moving_mask, ref.moving_mask)
    assert b.dominant == ref.dominant and calls == []
    c = MotionAnalysis(out.flow, out.confidence, 0.1, confidence_at=lambda ys, xs: calls.append(ys.size) or at(ys, xs))
    assert c.dominant == ref.dominant and c.foe == ref.foe and len(calls) == 1  # one grid, computed once


# --------------------------------------------------- the mask with the confidence where it reads it alone
@pytest.mark.parametrize("opening_px", [0, 1, 2, 3])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_moving_mask_reads_the_confidence_only_where_the_deviating_pixels_survive_the_opening(opening_px, seed) -> None:
    rng = np.random.default_rng(seed)
    base = similarity_flow(0.5, -0.3, 0.4, 1.005)
    flow = with_block(base, (3.0, -2.0)).copy()
    flow += np.where(rng.random((H, W, 1)) < 0.05, rng.normal(0.0, 3.0, (H, W, 2)), 0.0).astype(np.float32)
    flow[:6, :] += 4.0  # deviating pixels along the border too
    conf = rng.random((H, W)).astype(np.float32)  # confident and not, in specks, everywhere
    conf[25:60, 35:80] = 0.9
    threshold = MaskThreshold(opening_px=opening_px)
    m = dominant_motion(flow, ONES)
    full = moving_mask(flow, conf, m, threshold)
    assert full.any() and not full.all()
    read: list[np.ndarray] = []

    def conf_in(where: np.ndarray) -> np.ndarray:  # right where asked, anything (here the opposite) elsewhere
        read.append(where.copy())
        return np.where(where, conf, 1.0 - conf).astype(np.float32)

    np.testing.assert_array_equal(moving_mask(flow, conf_in, m, threshold), full)
    assert len(read) == 1 and read[0].mean() < 0.5  # a part of the image: the deviating pixels' opening
    surviving = moving_mask(flow, ONES, m, MaskThreshold(opening_px=opening_px, min_confidence=0.0)) > 0
    np.testing.assert_array_equal(read[0], surviving)


def test_moving_mask_reads_nothing_without_deviating_pixels_or_motion() -> None:
    base = similarity_flow(1.0, 0.0, 0.0, 1.0)

    def fail(where: np.ndarray) -> np.ndarray:
        raise AssertionError("the confidence was read")

    assert not moving_mask(base, fail, dominant_motion(base, ONES)).any()
    assert not moving_mask(base, fail, None).any()


def test_analysis_mask_takes_the_confidence_where_it_reads_it() -> None:
    from flow_node.bag.motion_scenes import motion_scene
    from flow_node.bag.scenes import render_grey_pair
    from flow_node.pipeline.stream import FlowStream, StreamSettings

    scene, _ = motion_scene("pan", (256, 192), np.random.default_rng(3), object_share=0.2, objects=1)
    i0, i1, _ = render_grey_pair(scene)
    stream = FlowStream(StreamSettings(config=FlowConfig.preset("realtime")))
    stream.process((255 * i0).astype(np.uint8), 0)
    out = stream.process((255 * i1).astype(np.uint8), 100_000_000)
    a = MotionAnalysis.of(out)
    mask = a.moving_mask
    assert mask.any() and not out.confidence_computed  # neither the fits nor the mask took the whole map
    np.testing.assert_array_equal(mask, moving_mask(out.flow, out.confidence(), a.dominant))
