"""Files and pictures: Middlebury .flo read/write, PNG frames, and the Middlebury colour wheel."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

from .errors import FileFormatError, InputError

FLO_MAGIC = 202021.25


def flo_parts(flow: np.ndarray) -> tuple[bytes, memoryview]:
    """(H, W, 2) flow as the two parts of a Middlebury .flo, to be written one after the other: the 12-byte
    header (float32 magic, int32 width, height) and the u, v interleaved little-endian float32 data, a view
    of ``flow`` itself when it is such an array, C-contiguous (else of a converted copy). Writing the view
    saves the copy (3.6 MB for a KITTI frame's flow, and the fresh pages it faults in)."""
    if flow.ndim != 3 or flow.shape[2] != 2:
        raise InputError(f"flow must be (H, W, 2), got {flow.shape}")
    h, w = flow.shape[:2]
    header = np.array([FLO_MAGIC], "<f4").tobytes() + np.array([w, h], "<i4").tobytes()
    return header, memoryview(np.ascontiguousarray(flow, dtype="<f4").reshape(-1).view(np.uint8))


def flo_bytes(flow: np.ndarray) -> bytes:
    """(H, W, 2) flow as the bytes of a Middlebury .flo (:func:`flo_parts` joined: one copy of the data)."""
    return b"".join(flo_parts(flow))


def write_flo(path: str | Path, flow: np.ndarray) -> None:
    """Write (H, W, 2) flow as a Middlebury .flo file (:func:`flo_bytes`); FileFormatError with the OS's
    reason (written through Python's file object, so a full disk is an error, not a silent short file)."""
    data = flo_bytes(flow)
    try:
        with open(path, "wb") as fh:
            fh.write(data)
    except OSError as exc:
        reason = exc.strerror or (os.strerror(exc.errno) if exc.errno else str(exc))
        raise FileFormatError(f"cannot write {path}: {reason}") from exc


def read_flo(path: str | Path) -> np.ndarray:
    """Read a Middlebury .flo file -> (H, W, 2) float32."""
    try:
        raw = Path(path).read_bytes()
    except OSError as exc:
        raise FileFormatError(f"cannot read {path}: {exc.strerror}") from exc
    if len(raw) < 12 or np.frombuffer(raw[:4], "<f4")[0] != np.float32(FLO_MAGIC):
        raise FileFormatError(f"{path} is not a .flo file (bad magic number)")
    w, h = (int(x) for x in np.frombuffer(raw[4:12], "<i4"))
    if w <= 0 or h <= 0 or len(raw) != 12 + 8 * w * h:
        raise FileFormatError(f"{path}: header says {w}x{h} but the file holds {len(raw) - 12} data bytes")
    return np.frombuffer(raw[12:], "<f4").reshape(h, w, 2).astype(np.float32)


def read_image(path: str | Path) -> np.ndarray:
    """Read an 8- or 16-bit PNG (or any format OpenCV reads), grey or colour, returned as RGB/grey array."""
    p = Path(path)
    if not p.is_file():
        raise FileFormatError(f"cannot read {path}: no such file")
    img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise FileFormatError(f"cannot read {path}: not an image OpenCV can decode")
    if img.ndim == 3 and img.shape[2] == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    elif img.ndim == 3 and img.shape[2] == 4:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2RGBA)
    return img


def _colour_wheel() -> np.ndarray:
    """The Middlebury colour wheel (55 hues: RY 15, YG 6, GC 4, CB 11, BM 13, MR 6) as (55, 3) RGB 0..255."""
    segments = [(15, (255, 0, 0), (255, 255, 0)), (6, (255, 255, 0), (0, 255, 0)),
                (4, (0, 255, 0), (0, 255, 255)), (11, (0, 255, 255), (0, 0, 255)),
                (13, (0, 0, 255), (255, 0, 255)), (6, (255, 0, 255), (255, 0, 0))]
    rows = []
    for n, start, end in segments:
        t = np.arange(n)[:, None] / n
        rows.append(np.array(start) * (1 - t) + np.array(end) * t)
    return np.concatenate(rows).astype(np.float64)


_WHEEL = _colour_wheel()


def flow_to_color(flow: np.ndarray, max_flow: float = 0.0, bgr: bool = False) -> np.ndarray:
    """Middlebury colour coding of (H, W, 2) flow -> (H, W, 3) uint8 (RGB, or BGR if asked).

    Hue is the direction, saturation the magnitude relative to ``max_flow`` px (a fixed scale so colours
    mean the same across frames; 0 means the frame's own maximum). Magnitudes above the scale are drawn
    darker; unknown (non-finite or >= 1e9) vectors are black.
    """
    if flow.ndim != 3 or flow.shape[2] != 2:
        raise InputError(f"flow must be (H, W, 2), got {flow.shape}")
    u = flow[..., 0].astype(np.float64)
    v = flow[..., 1].astype(np.float64)
    bad = ~np.isfinite(u) | ~np.isfinite(v) | (np.abs(u) >= 1e9) | (np.abs(v) >= 1e9)
    u = np.where(bad, 0.0, u)
    v = np.where(bad, 0.0, v)
    rad = np.hypot(u, v)
    scale = max_flow if max_flow > 0 else max(float(rad.max()), 1e-9)
    u, v, rad = u / scale, v / scale, rad / scale
    ncols = len(_WHEEL)
    angle = np.arctan2(-v, -u) / np.pi
    fk = (angle + 1) / 2 * (ncols - 1)
    k0 = np.floor(fk).astype(int)
    k1 = (k0 + 1) % ncols
    f = (fk - k0)[..., None]
    col = ((1 - f) * _WHEEL[k0] + f * _WHEEL[k1]) / 255.0
    r = rad[..., None]
    inside = r <= 1
    col = np.where(inside, 1 - r * (1 - col), col * 0.75)
    out = np.floor(255 * col).astype(np.uint8)
    out[bad] = 0
    return out[..., ::-1].copy() if bgr else out
