"""What the suite evaluates: one :class:`Sample` per frame pair, and the loaders of the recorded data
(Middlebury, ../shared/data/large, the bundled bags). The synthetic regimes are in :mod:`.synthetic`.

A sample carries its frames *as delivered* (uint8, uint16 or float32 grey/RGB; 10-bit content as uint16
with values up to 1023), because delivering them is part of what is being tested: flow_node gets exactly
these arrays. ``bits`` is the content's bit depth, which a peer that needs 8-bit input is told (see
:func:`bench.suite.methods.unit_grey`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flow_node.core.api import to_grey
from flow_node.core.flowio import read_flo, read_image

from ..common import DEFAULT_DATA, REPO, SEQUENCES

LARGE_DATA = REPO.parent / "shared" / "data" / "large"
BAGS = REPO / "bags"
MIDDLEBURY_QUICK = ("Dimetrodon", "Grove3", "RubberWhale")
LUMA = np.array([0.299, 0.587, 0.114])  # BT.601, as flow_node.bag.scenes.render_grey_pair


@dataclass(frozen=True)
class Sample:
    """One pair: frames f0, f1 ((H, W) or (H, W, 3); uint8, uint16 or float32 in [0, 1]), ground truth
    (H, W, 2) float32 px (>= 1e9 or non-finite = unknown), content bit depth, a variant label that the
    report groups by (e.g. '10 bit', 'gain 1.25 -0.02'; '' = none), and optionally the occluded pixels of
    frame 0 ((H, W) bool, True = not visible in frame 1 or leaving the image; their ground truth stays
    known, and the scores add ``aee_noc`` over the known pixels that are not occluded); and optionally the
    frames' validity masks ((H, W) bool each, False = the pixel's value is garbage; the scores then add
    ``aee_masked`` and ``aee_elsewhere``, :func:`bench.suite.metrics.score_pair`)."""

    name: str
    f0: np.ndarray
    f1: np.ndarray
    gt: np.ndarray
    bits: int = 8
    variant: str = ""
    occluded: np.ndarray | None = None
    valid: tuple[np.ndarray, np.ndarray] | None = None  # frames' validity masks (regime 'missing'), True = data

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) in px."""
        return int(self.f0.shape[1]), int(self.f0.shape[0])


def _grey_file(path: Path) -> np.ndarray:
    return to_grey(read_image(path), path.name)


def read_float(path: Path) -> np.ndarray:
    """An 8-bit PNG as float64 in [0, 1]: (H, W) grey or (H, W, 3) RGB (alpha dropped)."""
    img = read_image(path)
    if img.dtype != np.uint8:
        raise ValueError(f"{path}: expected an 8-bit image, got {img.dtype}")
    return (img[..., :3] if img.ndim == 3 else img).astype(np.float64) / 255.0


def middlebury(quick: bool, data: Path = DEFAULT_DATA) -> list[Sample]:
    """The 8 Middlebury training pairs frame10 -> frame11 (quick: 3 of them), grey float32 [0, 1] (BT.601
    luma, as flow_node.core.api.to_grey and the paper protocol read them)."""
    if not data.is_dir():
        raise FileNotFoundError(f"Middlebury data not found at {data}")
    names = MIDDLEBURY_QUICK if quick else SEQUENCES
    return [Sample(n, _grey_file(data / n / "frame10.png"), _grey_file(data / n / "frame11.png"),
                   read_flo(data / n / "flow10.flo")) for n in names]


def large(quick: bool, data: Path = LARGE_DATA) -> list[Sample]:
    """The large-motion pairs frame0 -> frame1 with flow.flo (quick: the two 640x480 TartanAir a/c)."""
    if not data.is_dir():
        raise FileNotFoundError(f"large-motion data not found at {data}")
    dirs = sorted(p for p in data.iterdir() if (p / "flow.flo").is_file())
    if quick:
        dirs = [p for p in dirs if p.name.startswith(("tartanair_a", "tartanair_c"))]
    return [Sample(p.name, _grey_file(p / "frame0.png"), _grey_file(p / "frame1.png"), read_flo(p / "flow.flo"))
            for p in dirs]


def bags(quick: bool, folder: Path = BAGS) -> list[Sample]:
    """Every consecutive image pair of every bundled bag with its ground-truth topic (quick: the first
    pair of each), frames decoded as the node would see them (mono8, mono16, rgb8, png)."""
    out = []
    for bag in sorted(p.parent for p in folder.glob("*/metadata.yaml")):
        stamps, frames, gts = read_bag(bag)
        bits = 16 if frames[stamps[0]][0].dtype == np.uint16 else 8
        pairs = [Sample(f"{bag.name}_{k:02d}", frames[a][0], frames[b][0], gts[b], bits, bag.name)
                 for k, (a, b) in enumerate(zip(stamps, stamps[1:], strict=False), 1) if b in gts]
        out.extend(pairs[:1] if quick else pairs)
    return out


def read_bag(folder: Path) -> tuple[list[int], dict[int, tuple[np.ndarray, str]], dict[int, np.ndarray]]:
    """A bag's image stamps (ns) in order, its images decoded as the node decodes them (codec.decode: array
    and encoding) and its ground truths ((H, W, 2) float32 px on DEFAULT_GT_TOPIC), by stamp."""
    from flow_node.bag.bagio import IMAGE, IMAGE_TYPES, deserialize, find_connections, open_bag, read_messages, stamp_ns
    from flow_node.bag.evaluate import DEFAULT_GT_TOPIC, read_ground_truth
    from flow_node.pipeline.codec import decode

    frames: dict[int, tuple[np.ndarray, str]] = {}
    truths: dict[int, object] = {}
    with open_bag(folder) as reader:
        gt_conns = find_connections(reader, DEFAULT_GT_TOPIC, (IMAGE,), "gt")
        img_conns = find_connections(reader, None, IMAGE_TYPES, "image", exclude=(DEFAULT_GT_TOPIC,))
        for conn, _, raw in read_messages(reader, list(img_conns) + list(gt_conns)):
            msg = deserialize(raw, conn.msgtype)
            if conn.topic == DEFAULT_GT_TOPIC:
                truths[stamp_ns(msg)] = msg
            else:
                frames[stamp_ns(msg)] = decode(msg)
    stamps = sorted(frames)
    return stamps, frames, {s: read_ground_truth(truths[s], frames[s][0].shape[:2], s) for s in stamps if s in truths}
