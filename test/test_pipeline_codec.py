"""Codec: every supported encoding decodes to the right pixels, padding/endianness honoured, bad images raise.

Messages are real rclpy sensor_msgs/Image objects and real rosbags messages (the two kinds the codec serves).
"""

from __future__ import annotations

import array

import cv2
import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore
from sensor_msgs.msg import CompressedImage, Image

from flow_node.core.errors import InputError
from flow_node.pipeline.codec import (
    SUPPORTED_ENCODINGS,
    MalformedImage,
    UnsupportedEncoding,
    array_to_image_fields,
    compressed_to_array,
    decode,
    image_to_array,
)

RNG = np.random.default_rng(7)
H, W = 6, 8


def ros_image(encoding: str, payload: np.ndarray, step: int, big: bool = False, height: int = H,
              width: int = W) -> Image:
    """An rclpy Image with raw row bytes ``payload`` (height rows of ``step`` bytes)."""
    msg = Image(height=height, width=width, encoding=encoding, is_bigendian=int(big), step=step)
    msg.data = array.array("B", payload.tobytes())
    return msg


def padded(rows: np.ndarray, pad: int) -> tuple[np.ndarray, int]:
    """Row bytes (H, row_bytes) with ``pad`` garbage bytes appended to each row -> (flat bytes, step)."""
    garbage = np.full((rows.shape[0], pad), 0xAB, np.uint8)
    out = np.concatenate([rows, garbage], axis=1)
    return out.reshape(-1), out.shape[1]


@pytest.mark.parametrize("encoding,dtype", [("mono8", np.uint8), ("8UC1", np.uint8), ("mono16", np.uint16),
                                            ("16UC1", np.uint16), ("32FC1", np.float32)])
@pytest.mark.parametrize("big", [False, True])
def test_mono_with_padding_and_endianness(encoding: str, dtype: type, big: bool) -> None:
    if dtype is np.float32:
        img = RNG.random((H, W)).astype(np.float32)
    else:
        img = RNG.integers(0, np.iinfo(dtype).max, (H, W), dtype=dtype, endpoint=True)
    wire = img.astype(np.dtype(dtype).newbyteorder(">" if big else "<"))
    flat, step = padded(wire.view(np.uint8).reshape(H, -1), pad=5)
    out = image_to_array(ros_image(encoding, flat, step, big))
    assert out.dtype == dtype and out.shape == (H, W)
    np.testing.assert_array_equal(out, img)


@pytest.mark.parametrize("encoding", ["rgb8", "bgr8", "rgba8", "bgra8"])
def test_colour_orders_give_rgb(encoding: str) -> None:
    rgb = RNG.integers(0, 255, (H, W, 3), dtype=np.uint8, endpoint=True)
    wire = rgb[..., ::-1] if encoding.startswith("bgr") else rgb
    if encoding.endswith("a8"):
        wire = np.concatenate([wire, np.full((H, W, 1), 77, np.uint8)], axis=2)
    flat, step = padded(np.ascontiguousarray(wire).reshape(H, -1), pad=3)
    out = image_to_array(ros_image(encoding, flat, step))
    assert out.shape == (H, W, 3) and out.dtype == np.uint8
    np.testing.assert_array_equal(out, rgb)


def mosaic(rgb: tuple[int, int, int], pattern: str, dtype: type) -> np.ndarray:
    """A Bayer mosaic of a uniform colour; ``pattern`` names the 2x2 top-left block, e.g. 'rggb'."""
    chan = {"r": 0, "g": 1, "b": 2}
    out = np.zeros((H, W), dtype)
    for k, c in enumerate(pattern):
        out[k // 2::2, k % 2::2] = rgb[chan[c]]
    return out


@pytest.mark.parametrize("pattern", ["rggb", "bggr", "gbrg", "grbg"])
@pytest.mark.parametrize("bits", [8, 16])
def test_bayer_patterns_demosaic_to_the_right_colour(pattern: str, bits: int) -> None:
    dtype = np.uint8 if bits == 8 else np.uint16
    colour = (200, 100, 30) if bits == 8 else (50000, 20000, 3000)
    raw = mosaic(colour, pattern, dtype)
    out = image_to_array(ros_image(f"bayer_{pattern}{bits}", raw.view(np.uint8), W * raw.itemsize))
    assert out.shape == (H, W, 3) and out.dtype == dtype
    # interior pixels of a uniform mosaic demosaic exactly to the colour (R and B swapped if mislabelled)
    np.testing.assert_allclose(out[2:-2, 2:-2].reshape(-1, 3).astype(float), np.tile(colour, ((H - 4) * (W - 4), 1)),
                               atol=1)


@pytest.mark.parametrize("encoding,y_at", [("yuv422", 1), ("uyvy", 1), ("yuv422_yuy2", 0), ("yuyv", 0)])
def test_yuv422_variants_decode_to_luma(encoding: str, y_at: int) -> None:
    luma = RNG.integers(16, 235, (H, W), dtype=np.uint8)
    chroma = RNG.integers(16, 240, (H, W), dtype=np.uint8)
    pairs = np.empty((H, W, 2), np.uint8)
    pairs[..., y_at], pairs[..., 1 - y_at] = luma, chroma
    flat, step = padded(pairs.reshape(H, -1), pad=4)
    out = image_to_array(ros_image(encoding, flat, step))
    np.testing.assert_array_equal(out, luma)


def test_all_listed_encodings_are_tested_here() -> None:
    tested = {"mono8", "8UC1", "mono16", "16UC1", "32FC1", "rgb8", "bgr8", "rgba8", "bgra8", "yuv422", "uyvy",
              "yuv422_yuy2", "yuyv", "rgb16", "bgr16", "8UC3", "32FC2"}
    tested |= {f"bayer_{p}{b}" for p in ("rggb", "bggr", "gbrg", "grbg") for b in (8, 16)}
    assert set(SUPPORTED_ENCODINGS) == tested


@pytest.mark.parametrize("encoding", ["rgb16", "bgr16"])
def test_16bit_colour(encoding: str) -> None:
    rgb = RNG.integers(0, 65535, (H, W, 3), dtype=np.uint16, endpoint=True)
    wire = np.ascontiguousarray(rgb[..., ::-1] if encoding == "bgr16" else rgb)
    out = image_to_array(ros_image(encoding, wire.view(np.uint8), W * 6))
    np.testing.assert_array_equal(out, rgb)


def test_8uc3_is_bgr_like_opencv() -> None:
    rgb = RNG.integers(0, 255, (H, W, 3), dtype=np.uint8, endpoint=True)
    out = image_to_array(ros_image("8UC3", np.ascontiguousarray(rgb[..., ::-1]), W * 3))
    np.testing.assert_array_equal(out, rgb)


def test_step_too_small_is_malformed() -> None:
    img = np.zeros((H, W), np.uint16)
    with pytest.raises(MalformedImage, match="step 10 < 16"):
        image_to_array(ros_image("mono16", img.view(np.uint8)[:, :10], 10))


@pytest.mark.parametrize("extra", [-1, 1])
def test_data_length_wrong_is_malformed(extra: int) -> None:
    data = np.zeros(H * W + extra, np.uint8)
    with pytest.raises(MalformedImage, match="data has"):
        image_to_array(ros_image("mono8", data, W))


def test_zero_size_and_odd_yuv_width_are_malformed() -> None:
    with pytest.raises(MalformedImage, match="zero size"):
        image_to_array(ros_image("mono8", np.zeros(0, np.uint8), 0, height=0, width=0))
    with pytest.raises(MalformedImage, match="odd"):
        image_to_array(ros_image("yuyv", np.zeros(H * 7 * 2, np.uint8), 14, width=7))


def test_unsupported_encoding_names_it_and_is_an_input_error() -> None:
    with pytest.raises(UnsupportedEncoding, match="'nv12'") as info:
        image_to_array(ros_image("nv12", np.zeros(H * W, np.uint8), W))
    assert isinstance(info.value, InputError)


def test_fields_round_trip_through_rclpy_and_rosbags_messages() -> None:
    flow = RNG.normal(0, 3, (H, W, 2)).astype(np.float32)
    fields = array_to_image_fields(flow, "32FC2")
    assert (fields["height"], fields["width"], fields["step"], fields["is_bigendian"]) == (H, W, W * 8, 0)
    rc = Image(**{k: v for k, v in fields.items() if k != "data"})
    rc.data = array.array("B", fields["data"].tobytes())
    np.testing.assert_array_equal(image_to_array(rc), flow)
    store = get_typestore(Stores.ROS2_JAZZY)
    rb_img = store.types["sensor_msgs/msg/Image"]
    hdr = store.types["std_msgs/msg/Header"](stamp=store.types["builtin_interfaces/msg/Time"](sec=1, nanosec=2),
                                             frame_id="cam")
    rb = rb_img(header=hdr, **fields)
    # through CDR and back, as the bag tools do
    back = store.deserialize_cdr(store.serialize_cdr(rb, rb_img.__msgtype__), rb_img.__msgtype__)
    np.testing.assert_array_equal(image_to_array(back), flow)
    bgr = RNG.integers(0, 255, (H, W, 3), dtype=np.uint8, endpoint=True)
    np.testing.assert_array_equal(image_to_array(rb_img(header=hdr, **array_to_image_fields(bgr, "bgr8"))),
                                  bgr[..., ::-1])


def test_fields_reject_wrong_dtype_and_decode_only_encodings() -> None:
    with pytest.raises(InputError, match="float32"):
        array_to_image_fields(np.zeros((H, W), np.float64), "32FC1")
    with pytest.raises(UnsupportedEncoding, match="decoding only"):
        array_to_image_fields(np.zeros((H, W), np.uint8), "bayer_rggb8")


def test_compressed_png_grey_colour_and_16bit() -> None:
    rgb = RNG.integers(0, 255, (H, W, 3), dtype=np.uint8, endpoint=True)
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(rgb[..., ::-1]))
    msg = CompressedImage(format="png")
    msg.data = array.array("B", buf.tobytes())
    out, label = decode(msg)
    np.testing.assert_array_equal(out, rgb)
    assert label == "compressed/png"
    g16 = RNG.integers(0, 65535, (H, W), dtype=np.uint16, endpoint=True)
    ok, buf = cv2.imencode(".png", g16)
    msg.data = array.array("B", buf.tobytes())
    out = compressed_to_array(msg)
    assert out.dtype == np.uint16
    np.testing.assert_array_equal(out, g16)


def test_compressed_garbage_and_depth_are_rejected() -> None:
    msg = CompressedImage(format="jpeg")
    msg.data = array.array("B", b"not a jpeg at all")
    with pytest.raises(MalformedImage, match="cannot decode"):
        compressed_to_array(msg)
    msg.format = "16UC1; compressedDepth png"
    with pytest.raises(UnsupportedEncoding):
        compressed_to_array(msg)
