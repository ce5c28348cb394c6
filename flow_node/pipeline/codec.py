"""sensor_msgs/Image and CompressedImage <-> numpy, duck-typed on the message fields.

One implementation for rclpy messages (the node) and rosbags messages (the bag tools): only the fields
``height, width, encoding, is_bigendian, step, data`` (Image) and ``format, data`` (CompressedImage) are read,
and ``data`` may be ``bytes``, ``array.array('B')``, a list of ints or a numpy uint8 array.

Decoded images are what :func:`flow_node.core.api.to_grey` accepts: grey ``(H, W)`` or RGB ``(H, W, 3)``
(always R, G, B order, alpha dropped), dtype uint8, uint16 or float32, in native byte order. Bayer mosaics are
demosaiced to RGB; YUV 4:2:2 images are returned as their luma plane (grey), which is exactly the grey the
engine would compute from them.

Size limit: an image (raw, or compressed as its header declares it) may have at most ``MAX_IMAGE_SIDE`` px a
side and ``MAX_IMAGE_PIXELS`` px in all; larger ones are rejected as :class:`MalformedImage` before any pixel
is decoded (a PNG header claiming 100000x100000 costs nothing). OpenCV decoder failures are rejections too.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from ..core.errors import InputError, one_line


class UnsupportedEncoding(InputError):
    """The image's encoding (or compressed format) is not one the codec can decode or encode."""


class MalformedImage(InputError):
    """The image's fields are inconsistent: step too small, data length wrong, zero size, undecodable."""


@dataclass(frozen=True)
class Encoding:
    """Layout of one raw encoding: element dtype, channels per pixel, and how to turn it into grey/RGB."""

    dtype: np.dtype
    channels: int
    kind: str  # "mono", "rgb", "bgr", "rgba", "bgra", "bayer", "yuv", "raw" (multi-channel float out)
    cv_code: int | None = None  # bayer demosaic code (to RGB)
    luma_index: int = 0  # yuv: byte offset of the first Y sample in each 4-byte macropixel


_U8, _U16, _F32 = np.dtype(np.uint8), np.dtype(np.uint16), np.dtype(np.float32)

# ROS names the Bayer pattern by its top-left 2x2 block, OpenCV by the 2x2 block starting at (1, 1) of the
# second row/column, so ROS rggb is OpenCV "BG" (as in cv_bridge).
_BAYER = {"rggb": cv2.COLOR_BayerBG2RGB, "bggr": cv2.COLOR_BayerRG2RGB,
          "gbrg": cv2.COLOR_BayerGR2RGB, "grbg": cv2.COLOR_BayerGB2RGB}

ENCODINGS: dict[str, Encoding] = {
    "mono8": Encoding(_U8, 1, "mono"),
    "8UC1": Encoding(_U8, 1, "mono"),
    "mono16": Encoding(_U16, 1, "mono"),
    "16UC1": Encoding(_U16, 1, "mono"),
    "32FC1": Encoding(_F32, 1, "mono"),
    "rgb8": Encoding(_U8, 3, "rgb"),
    "bgr8": Encoding(_U8, 3, "bgr"),
    "rgba8": Encoding(_U8, 4, "rgba"),
    "bgra8": Encoding(_U8, 4, "bgra"),
    "rgb16": Encoding(_U16, 3, "rgb"),
    "bgr16": Encoding(_U16, 3, "bgr"),
    "8UC3": Encoding(_U8, 3, "bgr"),
    "32FC2": Encoding(_F32, 2, "raw"),
    # YUV 4:2:2, 2 bytes per pixel: UYVY (ROS "yuv422" and "uyvy") and YUYV ("yuv422_yuy2" and "yuyv")
    "yuv422": Encoding(_U8, 2, "yuv", luma_index=1),
    "uyvy": Encoding(_U8, 2, "yuv", luma_index=1),
    "yuv422_yuy2": Encoding(_U8, 2, "yuv", luma_index=0),
    "yuyv": Encoding(_U8, 2, "yuv", luma_index=0),
}
for _pattern, _code in _BAYER.items():
    ENCODINGS[f"bayer_{_pattern}8"] = Encoding(_U8, 1, "bayer", _code)
    ENCODINGS[f"bayer_{_pattern}16"] = Encoding(_U16, 1, "bayer", _code)

SUPPORTED_ENCODINGS: tuple[str, ...] = tuple(ENCODINGS)

MAX_IMAGE_SIDE = 16384  # px, either side
MAX_IMAGE_PIXELS = 1 << 26  # 67 Mpx (8192 x 8192)


def check_size(width: int, height: int, what: str) -> None:
    """MalformedImage unless 0 < width, height <= MAX_IMAGE_SIDE and width * height <= MAX_IMAGE_PIXELS."""
    if width <= 0 or height <= 0:
        raise MalformedImage(f"{what} has zero size ({width}x{height})")
    if max(width, height) > MAX_IMAGE_SIDE or width * height > MAX_IMAGE_PIXELS:
        raise MalformedImage(f"{what} is {width}x{height} px, over the limit of {MAX_IMAGE_SIDE} px a side "
                             f"and {MAX_IMAGE_PIXELS} px")


_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
# JPEG start-of-frame markers (baseline, extended, progressive, lossless, ...; not DHT C4, JPG C8, DAC CC)
_JPEG_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}


def declared_size(buf: bytes | np.ndarray) -> tuple[int, int] | None:
    """(width, height) a PNG or JPEG header declares, without decoding pixels; None for other formats or
    a header too short to tell (the decoder then rejects it)."""
    head = bytes(buf[:24])
    if head.startswith(_PNG_MAGIC) and len(head) >= 24 and head[12:16] == b"IHDR":
        w, h = struct.unpack(">II", head[16:24])
        return w, h
    if not head.startswith(b"\xff\xd8"):
        return None
    data = bytes(buf[: 1 << 20])  # SOF comes after the tables; a megabyte of markers is plenty
    pos = 2
    while pos + 9 <= len(data):
        if data[pos] != 0xFF:
            return None
        marker = data[pos + 1]
        if marker == 0xFF:  # fill byte
            pos += 1
            continue
        if marker in _JPEG_SOF:
            h, w = struct.unpack(">HH", data[pos + 5:pos + 9])
            return w, h
        if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:
            pos += 2
            continue
        pos += 2 + struct.unpack(">H", data[pos + 2:pos + 4])[0]
    return None


def cv_reason(exc: BaseException) -> str:
    """The one-line reason of an OpenCV error (its text after ``error:``, without the source location)."""
    text = one_line(exc, None)
    return text.partition(" error: ")[2] or text or type(exc).__name__


def decode_bytes(buf: np.ndarray, what: str) -> np.ndarray:
    """Decode an encoded image (PNG, JPEG, TIFF, ... : what OpenCV reads) held in a flat uint8 array.

    Returns grey (H, W) or RGB (H, W, 3) (alpha dropped) in the file's dtype. The declared size is checked
    against the limit first; any decoder failure is a MalformedImage naming ``what``.
    """
    if buf.size == 0:
        raise MalformedImage(f"{what} has no data")
    size = declared_size(buf)
    if size is not None:
        check_size(*size, what)
    try:
        img = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
    except cv2.error as exc:
        raise MalformedImage(f"OpenCV cannot decode {what}: {cv_reason(exc)}") from None
    if img is None:
        raise MalformedImage(f"OpenCV cannot decode {what} ({buf.size} bytes)")
    check_size(img.shape[1], img.shape[0], what)
    if img.ndim == 3 and img.shape[2] == 1:
        return img[:, :, 0]
    if img.ndim == 3:
        return np.ascontiguousarray(img[:, :, 2::-1])  # OpenCV decodes BGR(A); drop alpha, make RGB
    return img


def _data_bytes(data: Any) -> np.ndarray:
    """The message's ``data`` as a flat uint8 numpy view (no copy for buffers)."""
    if isinstance(data, np.ndarray):
        return np.ascontiguousarray(data).reshape(-1).view(np.uint8)
    try:
        return np.frombuffer(memoryview(data), dtype=np.uint8)
    except TypeError:
        return np.asarray(data, dtype=np.uint8).reshape(-1)


def _lookup(encoding: str) -> Encoding:
    """The layout of ``encoding``; raises UnsupportedEncoding listing what is supported."""
    enc = ENCODINGS.get(encoding)
    if enc is None:
        raise UnsupportedEncoding(f"unsupported encoding {encoding!r}; supported: {', '.join(SUPPORTED_ENCODINGS)}")
    return enc


def raw_pixels(msg: Any) -> tuple[np.ndarray, Encoding]:
    """The pixel elements of an Image message as (H, W, C) in native byte order, padding removed.

    Validates height/width > 0, step >= width * bytes per pixel, len(data) == step * height.
    """
    height, width, step = int(msg.height), int(msg.width), int(msg.step)
    enc = _lookup(str(msg.encoding))
    check_size(width, height, f"{msg.encoding} image")
    row_bytes = width * enc.channels * enc.dtype.itemsize
    if step < row_bytes:
        raise MalformedImage(f"{msg.encoding} {width}x{height}: step {step} < {row_bytes} bytes per row")
    buf = _data_bytes(msg.data)
    if buf.size != step * height:
        raise MalformedImage(f"{msg.encoding} {width}x{height}: data has {buf.size} bytes, "
                             f"expected step * height = {step * height}")
    rows = buf.reshape(height, step)[:, :row_bytes]
    order = ">" if bool(msg.is_bigendian) else "<"
    dtype = enc.dtype.newbyteorder(order) if enc.dtype.itemsize > 1 else enc.dtype
    pixels = np.ascontiguousarray(rows).view(dtype).reshape(height, width, enc.channels)
    return pixels.astype(enc.dtype.newbyteorder("="), copy=False), enc


def image_to_array(msg: Any) -> np.ndarray:
    """Decode a sensor_msgs/Image (rclpy or rosbags) to grey (H, W) or RGB (H, W, 3).

    dtype follows the encoding (uint8, uint16 or float32); raises UnsupportedEncoding / MalformedImage.
    Multi-channel float encodings (32FC2) decode to (H, W, 2) float32, e.g. to read flow back.
    """
    px, enc = raw_pixels(msg)
    if enc.kind == "mono":
        return px[:, :, 0]
    if enc.kind == "raw":
        return px
    if enc.kind == "rgb":
        return px
    if enc.kind in ("bgr", "bgra"):
        return np.ascontiguousarray(px[:, :, 2::-1])
    if enc.kind == "rgba":
        return np.ascontiguousarray(px[:, :, :3])
    if enc.kind == "bayer":
        if px.shape[0] < 2 or px.shape[1] < 2:
            raise MalformedImage(f"{msg.encoding}: a Bayer image needs at least 2x2 pixels")
        return cv2.cvtColor(px[:, :, 0], enc.cv_code)
    # yuv 4:2:2: every pixel has its own Y sample at a fixed byte of its 2-byte pair
    if px.shape[1] % 2:
        raise MalformedImage(f"{msg.encoding}: width {px.shape[1]} is odd; 4:2:2 needs pixel pairs")
    return np.ascontiguousarray(px[:, :, enc.luma_index])


def compressed_to_array(msg: Any) -> np.ndarray:
    """Decode a sensor_msgs/CompressedImage (png, jpeg, ... via OpenCV) to grey (H, W) or RGB (H, W, 3)."""
    fmt = str(msg.format)
    if "compresseddepth" in fmt.lower():
        raise UnsupportedEncoding(f"compressed format {fmt!r} (compressedDepth) is not supported")
    return decode_bytes(_data_bytes(msg.data), f"the compressed image (format {fmt!r})")


def array_to_image_fields(arr: np.ndarray, encoding: str) -> dict[str, Any]:
    """The sensor_msgs/Image fields (except header) for ``arr`` laid out as ``encoding`` says.

    ``arr`` must already be in the encoding's channel order (e.g. B, G, R for bgr8) with the encoding's
    dtype: (H, W) or (H, W, C). Returns ``height, width, encoding, is_bigendian (0), step, data`` with data
    a contiguous 1-D numpy uint8 array (rosbags takes it as is; rclpy's setter would copy it into an
    ``array.array``, which :func:`flow_node.ros.messages.image_msg` avoids). Bayer and YUV encodings are decode-only.
    """
    enc = _lookup(encoding)
    if enc.kind in ("bayer", "yuv"):
        raise UnsupportedEncoding(f"encoding {encoding!r} is supported for decoding only")
    a = np.asarray(arr)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[2] != enc.channels or a.dtype != enc.dtype:
        want = "(H, W)" if enc.channels == 1 else f"(H, W, {enc.channels})"
        raise InputError(f"{encoding} needs an array of shape {want} and dtype {enc.dtype}, "
                         f"got {np.asarray(arr).shape} {np.asarray(arr).dtype}")
    a = np.ascontiguousarray(a, dtype=enc.dtype.newbyteorder("<"))
    h, w = a.shape[:2]
    return {"height": h, "width": w, "encoding": encoding, "is_bigendian": 0,
            "step": w * enc.channels * enc.dtype.itemsize, "data": a.reshape(-1).view(np.uint8)}


def decode(msg: Any) -> tuple[np.ndarray, str]:
    """Decode an Image or a CompressedImage (told apart by their fields) -> (array, encoding label).

    The label is the Image encoding, or ``compressed/<format>``; the stream resets when it changes.
    """
    if hasattr(msg, "encoding"):
        return image_to_array(msg), str(msg.encoding)
    return compressed_to_array(msg), f"compressed/{msg.format}"
