"""Hostile frames (issue 15, items 1 and 3): garbage is rejected with a reason, never solved into NaN and
published; oversized compressed images are rejected from their header, in the codec, the stream and the live
node over real DDS."""

from __future__ import annotations

import array
import struct
import zlib

import cv2
import numpy as np
import pytest
import small_frames
from frame_messages import I0, I1, image, mono8, set_stamp
from sensor_msgs.msg import CompressedImage

from flow_node.core.api import FLOAT_INPUT_LIMIT, FlowEstimator, to_grey
from flow_node.core.errors import InputError, NonFiniteResult
from flow_node.core.layout import ensure_finite
from flow_node.pipeline.codec import MAX_IMAGE_SIDE, MalformedImage, declared_size, decode, decode_bytes
from flow_node.pipeline.stream import FlowStream, StreamSettings


def png_claiming(width: int, height: int) -> bytes:
    """A PNG whose IHDR (with a valid CRC) claims ``width`` x ``height``; its pixel data is for 4x4."""
    ok, buf = cv2.imencode(".png", np.zeros((4, 4), np.uint8))
    b = bytearray(buf.tobytes())
    b[16:24] = struct.pack(">II", width, height)
    b[29:33] = struct.pack(">I", zlib.crc32(bytes(b[12:29])))
    return bytes(b)


def jpeg_claiming(width: int, height: int) -> bytes:
    """A JPEG whose start-of-frame claims ``width`` x ``height``."""
    ok, buf = cv2.imencode(".jpg", np.full((8, 8), 100, np.uint8))
    b = bytearray(buf.tobytes())
    sof = b.index(b"\xff\xc0")
    b[sof + 5:sof + 9] = struct.pack(">HH", height, width)
    return bytes(b)


def compressed(data: bytes, stamp: int, fmt: str = "png") -> CompressedImage:
    msg = CompressedImage(format=fmt)
    msg.data = array.array("B", data)
    set_stamp(msg, stamp)
    return msg


def huge_float_frame(value: float = 1e30) -> np.ndarray:
    """A 32FC1-like frame: the test texture with a block of huge finite values."""
    f = I0.astype(np.float32).copy()
    f[10:30, 20:50] = value
    return f


def test_huge_finite_floats_are_rejected_with_the_reason() -> None:
    with pytest.raises(InputError, match=r"float values reach 1e\+30"):
        to_grey(huge_float_frame())
    stream = FlowStream(StreamSettings(config=small_frames.CONFIG))
    assert stream.process(I0.astype(np.float32), 1, "32FC1") is None
    with pytest.raises(InputError, match="float values reach"):
        stream.process(huge_float_frame(), 2, "32FC1")
    out = stream.process(I1.astype(np.float32), 3, "32FC1")  # the good frame pairs with the kept one
    assert out is not None and out.previous_stamp_ns == 1 and np.isfinite(out.flow).all()
    # at the limit still accepted (and the flow is finite)
    to_grey(huge_float_frame(FLOAT_INPUT_LIMIT))


def test_engine_output_check_flags_non_finite_flow() -> None:
    flow = np.zeros((4, 5, 2), np.float32)
    assert ensure_finite(flow) is flow
    for bad in (np.nan, np.inf, -np.inf):
        flow[1, 2, 0] = bad
        with pytest.raises(NonFiniteResult, match="1 NaN/inf value"):
            ensure_finite(flow)
    # frames that skipped to_grey's validation (estimate_grey trusts its caller) and overflow the solver
    i0 = np.full((40, 48), 1e30, np.float32)
    i1 = np.roll(i0 * np.linspace(0, 1, 48, dtype=np.float32), 1, axis=1)
    with np.errstate(all="ignore"), pytest.raises(NonFiniteResult):
        FlowEstimator(small_frames.CONFIG).estimate_grey(i0 * np.inf, i1)


@pytest.mark.parametrize("make,fmt", [(png_claiming, "png"), (jpeg_claiming, "jpeg")])
def test_oversized_header_is_rejected_before_decoding(make, fmt: str) -> None:
    data = make(60000, 50000)
    assert declared_size(np.frombuffer(data, np.uint8)) == (60000, 50000)
    with pytest.raises(MalformedImage, match=f"60000x50000 px, over the limit of {MAX_IMAGE_SIDE} px"):
        decode(compressed(data, 1, fmt))
    # a PNG at 100000x100000 (OpenCV's own size error before the fix) and a normal one
    with pytest.raises(MalformedImage, match="100000x100000"):
        decode_bytes(np.frombuffer(png_claiming(100000, 100000), np.uint8), "frame.png")
    ok, buf = cv2.imencode(".png", mono8(I0))
    assert decode_bytes(buf.reshape(-1), "ok.png").shape == I0.shape


def test_opencv_decoder_errors_are_rejections() -> None:
    png = png_claiming(4, 4)
    truncated = png[: len(png) - 20]
    for data in (truncated, b"\x89PNG\r\n\x1a\n" + b"\0" * 40, b"garbage"):
        with pytest.raises(MalformedImage, match="cannot decode"):
            decode(compressed(data, 1))


@pytest.mark.ros
def test_node_rejects_garbage_frames_and_never_publishes_them() -> None:
    """Over real DDS: 1e30 floats, a NaN frame and a PNG claiming 100000x100000 are rejected (diagnostics
    WARN, engine errors 0), nothing is published for them, and good frames still give flow."""
    from ros_helpers import Harness, wait_for  # rclpy: loaded by this DDS test only, not under -m "not ros"

    h = Harness("/t_harden", {"use_compressed": False}, name="flow_harden")
    try:
        h.send_frame(image(I0.astype(np.float32), "32FC1", 10))
        for k, bad in enumerate((huge_float_frame(), huge_float_frame(np.nan), huge_float_frame(3e38))):
            h.send_frame(image(bad, "32FC1", 11 + k))
        assert h.totals.rejected == 3 and h.totals.published == 0 and h.totals.errors == 0
        n = h.count("flow")
        h.send_frame(image(I1.astype(np.float32), "32FC1", 20))
        wait_for(lambda: h.count("flow") > n, 5.0, "flow after the rejected frames")
        flows = [np.frombuffer(bytes(m.data), np.float32) for _, m in h.received["flow"]]
        assert all(np.isfinite(f).all() for f in flows)
        st = wait_for(lambda: [s for _, s in h.received["diagnostics"]
                               if dict((kv.key, kv.value) for kv in s.values)["frames rejected"] == "3"],
                      5.0, "diagnostics with the rejections")[-1]
        values = {kv.key: kv.value for kv in st.values}
        assert values["engine errors"] == "0" and "float values reach" in values["last rejection"]
    finally:
        h.close()
    c = Harness("/t_harden_c", {"use_compressed": True}, name="flow_harden_c", color=False)
    try:
        c.send_frame(compressed(png_claiming(100000, 100000), 30))
        assert c.totals.rejected == 1 and c.totals.errors == 0
        st = wait_for(lambda: [s for _, s in c.received["diagnostics"]
                               if dict((kv.key, kv.value) for kv in s.values)["frames rejected"] == "1"],
                      5.0, "diagnostics with the rejection")[-1]
        assert st.level != st.OK and "engine failed" not in st.message  # flagged: not OK, not an engine error
        assert "100000x100000" in {kv.key: kv.value for kv in st.values}["last rejection"]
    finally:
        c.close()
