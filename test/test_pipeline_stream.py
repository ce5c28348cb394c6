"""The per-frame stream: pairs, reset rules, settings swap on the next frame, input_scale, outputs."""

from __future__ import annotations

import numpy as np
import pytest
import small_frames
from synth import constant_flow, pair_from_flow, texture

from flow_node.core.errors import ConfigError, InputError
from flow_node.core.metrics import aee
from flow_node.pipeline.stream import FlowStream, StreamSettings, magnitude, scaled_shape, summarise

H, W = 60, 80
FAST = small_frames.CONFIG
GT = constant_flow(H, W, 1.5, -0.75)
I0, I1 = pair_from_flow(texture(H, W, seed=1), GT)


def stream(**kw: object) -> FlowStream:
    return FlowStream(StreamSettings(config=FAST, **kw))


def test_first_frame_starts_a_pair_then_flow_is_accurate() -> None:
    s = stream()
    assert s.process(I0, 100) is None and s.last_reset_reason == "first frame"
    out = s.process(I1, 200)
    assert out is not None
    assert out.flow.shape == (H, W, 2) and out.flow.dtype == np.float32
    assert aee(out.flow, GT) < 0.15  # measured 0.06
    assert (out.stamp_ns, out.previous_stamp_ns, out.model, out.backend, out.scale) == (200, 100, "l1_tv",
                                                                                        "numpy", 1.0)
    np.testing.assert_allclose(out.magnitude, np.hypot(out.flow[..., 0], out.flow[..., 1]), rtol=1e-6)
    assert abs(out.summary.mean - np.hypot(1.5, 0.75)) < 0.2
    assert out.seconds > 0 and out.stats.total_iterations > 0


def test_uint8_and_colour_frames_give_the_same_motion() -> None:
    s = stream()
    rgb0 = np.repeat((I0 * 255).round().astype(np.uint8)[..., None], 3, axis=2)
    rgb1 = np.repeat((I1 * 255).round().astype(np.uint8)[..., None], 3, axis=2)
    s.process(rgb0, 0, "rgb8")
    out = s.process(rgb1, 1, "rgb8")
    assert aee(out.flow, GT) < 0.2


def test_resets_on_size_encoding_and_stamp_going_back() -> None:
    s = stream()
    s.process(I0, 10, "mono8")
    assert s.process(I1, 20, "mono8") is not None
    assert s.process(I0[:40, :60], 30, "mono8") is None
    assert s.last_reset_reason.startswith("size changed")
    assert s.process(I1[:40, :60], 40, "mono8") is not None
    assert s.process(I1[:40, :60], 50, "mono16") is None
    assert s.last_reset_reason.startswith("encoding changed")
    assert s.process(I0[:40, :60], 5, "mono16") is None
    assert s.last_reset_reason.startswith("stamp went back")
    out = s.process(I1[:40, :60], 6, "mono16")
    assert out is not None and out.previous_stamp_ns == 5


def test_manual_reset_applies_on_next_frame() -> None:
    s = stream()
    s.process(I0, 1)
    s.reset()
    assert s.process(I1, 2) is None and s.last_reset_reason == "reset requested"
    # the frame after a reset pairs with the frame that followed it: motion I1 -> I0 is -GT
    out = s.process(I0, 3)
    assert aee(out.flow, -GT) < 0.2


def test_config_swap_applies_on_the_next_frame_only() -> None:
    s = stream()
    s.process(I0, 1)
    applied = s.update(config=FAST.replace(model="l2_l2", alpha=0.05))
    assert applied.config.model == "l2_l2" and s.settings.config.model == "l1_tv"  # not yet
    out = s.process(I1, 2)
    assert out is not None, "a config change must not reset the pair"
    assert out.model == "l2_l2" and s.settings.config.alpha == 0.05


def test_invalid_update_raises_and_changes_nothing() -> None:
    s = stream()
    with pytest.raises(ConfigError, match="input_scale"):
        s.update(input_scale=0.0)
    with pytest.raises(ConfigError, match="color_max_flow"):
        s.update(color_max_flow=-1.0)
    s.process(I0, 1)
    out = s.process(I1, 2)
    assert out.scale == 1.0 and out.color_max_flow == 10.0


def test_input_scale_processes_and_publishes_at_reduced_resolution() -> None:
    s = stream(input_scale=0.5)
    s.process(I0, 1)
    out = s.process(I1, 2)
    assert out.flow.shape == (H // 2, W // 2, 2) and out.scale == 0.5
    # vectors are in pixels of the half-size image: half the full-resolution motion
    half = GT[::2, ::2] * 0.5
    assert aee(out.flow, half) < 0.25  # measured 0.15
    assert aee(out.flow, GT[::2, ::2]) > 0.6  # not full-resolution pixels
    # changing the scale resets (the stored frame has the other size)
    s.update(input_scale=1.0)
    assert s.process(I0, 3) is None and s.last_reset_reason == "input_scale changed"


def test_bad_frame_raises_and_keeps_the_previous_one() -> None:
    s = stream()
    s.process(I0, 1)
    bad = I1.copy()
    bad[3, 3] = np.nan
    with pytest.raises(InputError, match="NaN"):
        s.process(bad, 2)
    out = s.process(I1, 3)
    assert out is not None and out.previous_stamp_ns == 1 and aee(out.flow, GT) < 0.15


def test_colour_is_lazy_cached_and_bgr() -> None:
    s = stream()
    s.process(I0, 1)
    out = s.process(I1, 2)
    assert not out.color_computed and not out.confidence_computed
    col = out.color()
    assert col.shape == (H, W, 3) and col.dtype == np.uint8 and out.color() is col and out.color_computed
    # flow (1.5, -0.75) at a 10 px scale is pale; the wheel puts rightward motion in the red-ish half:
    # in BGR order the last channel (red) must dominate the first (blue)
    centre = col[20:40, 20:60].reshape(-1, 3).astype(int).mean(axis=0)
    assert centre[2] > centre[0]


def test_summary_and_magnitude_numbers() -> None:
    flow = np.zeros((10, 10, 2), np.float32)
    flow[..., 0] = np.arange(100, dtype=np.float32).reshape(10, 10) * 0.6
    flow[..., 1] = np.arange(100, dtype=np.float32).reshape(10, 10) * 0.8
    mag = magnitude(flow)
    np.testing.assert_allclose(mag.reshape(-1), np.arange(100), rtol=1e-6)
    s = summarise(mag)
    assert s.mean == pytest.approx(49.5) and s.p95 == pytest.approx(94.0) and s.max == pytest.approx(99.0)


def test_scaled_shape() -> None:
    assert scaled_shape((480, 640), 0.5) == (240, 320)
    assert scaled_shape((3, 3), 0.1) == (2, 2)


def test_confidence_is_judged_on_px_per_frame_whatever_the_units() -> None:
    """flow_units px/s scales the flow by 1 / interval; the confidence (a data residual at x + flow) must
    still be computed on the displacement over the pair, so it is the same in both units."""
    s = stream()
    s.process(I0, 0)
    out = s.process(I1, 50_000_000)  # 20 Hz: px/s is 20x px/frame
    fast = out.in_units("px/s")
    assert np.allclose(fast.flow, 20.0 * out.flow) and out.in_units("px/frame") is out
    conf = out.confidence()
    assert conf.mean() > 0.5  # the right flow is mostly trusted
    np.testing.assert_allclose(fast.confidence(), conf, atol=1e-6)


def test_flow_units_are_a_stream_setting_validated_once() -> None:
    """StreamSettings.flow_units: checked on construction and on update (ConfigError, nothing scheduled);
    the stream divides by each pair's own interval and rejects a pair without one."""
    with pytest.raises(ConfigError, match="flow_units: 'm/s' is not one of px/frame, px/s"):
        StreamSettings(flow_units="m/s")
    s = stream(flow_units="px/s")
    s.process(I0, 0)
    out = s.process(I1, 250_000_000)  # 4 Hz
    assert out is not None and np.allclose(out.flow, 4.0 * out.frame_flow)
    assert np.allclose(out.magnitude, magnitude(4.0 * out.frame_flow))
    with pytest.raises(InputError, match="0 ns apart"):
        s.process(I0, 250_000_000)
    with pytest.raises(ConfigError, match="flow_units"):
        s.update(flow_units="m/s")
    assert s.update(flow_units="px/frame").flow_units == "px/frame"
    out = s.process(I1, 300_000_000)
    assert out is not None and out.frame_flow is None and aee(out.flow, GT) < 0.15


def test_stream_mode_predicts_steady_motion_and_falls_back_on_cut_gap_and_reset() -> None:
    """With a stream preset the second and later pairs of a steady pan are solved from the previous flow
    (and stay accurate); a scene cut, a dropped run of frames (stamp gap) fall back to the full solve and
    are counted; a reset or a size change forgets the previous flow (no prediction, no fallback)."""
    from flow_node.bag.scenes import AffineMotion, Layer, Scene, Texture
    from flow_node.core.config import FlowConfig

    def scene(seed: int, velocity: tuple[float, float]) -> Scene:
        tex = Texture.random(np.random.default_rng(seed))
        return Scene("pan", (96, 72), (Layer(tex, AffineMotion((47.5, 35.5), velocity)),))

    def frame(sc: Scene, t: int) -> np.ndarray:
        return np.clip(np.rint(sc.render(t) * 255), 0, 255).astype(np.uint8)

    pan, other = scene(2, (1.5, -0.5)), scene(9, (-1.0, 1.0))
    # one stream level: on these 96x72 frames a second one would be 24x18 px, too coarse to judge a prediction
    cfg = FlowConfig.preset("stream_fast").replace(backend="numpy", stream_levels=1)
    st = FlowStream(StreamSettings(config=cfg))
    period = 33_000_000
    assert st.process(frame(pan, 0), 0, "rgb8") is None
    kinds = []
    for t in range(1, 5):
        out = st.process(frame(pan, t), t * period, "rgb8")
        kinds.append(out.stats.stream)
        assert aee(out.flow, pan.ground_truth(t).astype(np.float32)) < 0.25
    assert kinds == ["", "predicted", "predicted", "predicted"]
    assert (st.stream_totals.predicted, st.stream_totals.fallbacks) == (3, 0)
    out = st.process(frame(other, 0), 5 * period, "rgb8")  # scene cut
    assert out.stats.stream.startswith(("full: prediction does not fit", "full: exposure step"))
    out = st.process(frame(other, 1), 6 * period, "rgb8")  # the cut pair's flow is unreliable
    assert out.stats.stream.startswith("full: previous flow unreliable")
    assert st.process(frame(other, 2), 7 * period, "rgb8").stats.stream == "predicted"
    out = st.process(frame(other, 3), 11 * period, "rgb8")  # 3 frames dropped
    assert out.stats.stream.startswith("full: stamp gap (4.00x")
    assert (st.stream_totals.predicted, st.stream_totals.fallbacks) == (4, 3)
    assert st.stream_totals.last_fallback.startswith("stamp gap")
    st.reset()
    assert st.process(frame(other, 4), 12 * period, "rgb8") is None
    assert st.process(frame(other, 5), 13 * period, "rgb8").stats.stream == ""
