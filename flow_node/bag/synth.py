"""`flow_bag synth`: render a synthetic scene and write it as a rosbag2 with exact ground-truth flow.

Topics: ``/camera/image_raw`` (sensor_msgs/Image; or ``/camera/image_raw/compressed``,
sensor_msgs/CompressedImage, for the png/jpeg encodings) and ``/camera/flow_gt`` (sensor_msgs/Image 32FC2,
flow from the previous frame to this one, on every frame but the first, with the header of the newer frame).
The output depends only on the arguments: the same command writes the same bytes.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ..core.errors import ConfigError
from ..pipeline.codec import array_to_image_fields
from .bagio import COMPRESSED, IMAGE, NS, BagError, BagWriter, compressed_message, header, image_message
from .motion_scenes import SYNTH_SCENES, synth_scene
from .scenes import SCENES, make_scene

IMAGE_TOPIC = "/camera/image_raw"
GT_TOPIC = "/camera/flow_gt"
FRAME_ID = "camera"
START_NS = 1_700_000_000 * NS  # fixed epoch of the first frame, so bags are reproducible
RAW_ENCODINGS = ("mono8", "mono16", "rgb8", "bgr8", "32FC1")
COMPRESSED_ENCODINGS = ("png", "jpeg")
ENCODINGS = RAW_ENCODINGS + COMPRESSED_ENCODINGS


ALL_SCENES = SCENES + tuple(SYNTH_SCENES)  # the flow scenes, then those with known derived outputs
MAX_SIDE = 4096  # px: the renderer works in float64, a few arrays of the frame size at once

@dataclass(frozen=True)
class SynthSpec:
    """What to render: scene, frame count, size (width, height), rate, noise sigma (fraction of full
    scale), brightness change per frame (relative), encoding, storage and seed."""

    scene: str = "translation"
    frames: int = 8
    size: tuple[int, int] = (128, 96)
    fps: float = 10.0
    noise: float = 0.0
    brightness: float = 0.0
    encoding: str = "mono8"
    storage: str = "mcap"
    seed: int = 0

    def __post_init__(self) -> None:
        if self.scene not in ALL_SCENES:
            raise ConfigError(f"unknown scene {self.scene!r}; choose one of {', '.join(ALL_SCENES)}")
        if self.encoding not in ENCODINGS:
            raise ConfigError(f"unknown encoding {self.encoding!r}; choose one of {', '.join(ENCODINGS)}")
        if self.frames < 2:
            raise ConfigError(f"frames must be >= 2, got {self.frames}")
        if min(self.size) < 8 or max(self.size) > MAX_SIDE:
            raise ConfigError(f"size must be from 8x8 to {MAX_SIDE}x{MAX_SIDE}, got {self.size[0]}x{self.size[1]}")
        if not 0.0 < self.fps <= 1000.0:
            raise ConfigError(f"fps must be in (0, 1000], got {self.fps}")
        if not 0.0 <= self.noise <= 0.5:
            raise ConfigError(f"noise must be in [0, 0.5], got {self.noise}")
        if not -0.2 <= self.brightness <= 0.2:
            raise ConfigError(f"brightness must be in [-0.2, 0.2] per frame, got {self.brightness}")

    @property
    def image_topic(self) -> str:
        return IMAGE_TOPIC + "/compressed" if self.encoding in COMPRESSED_ENCODINGS else IMAGE_TOPIC


def frame_stamp(spec: SynthSpec, t: int) -> int:
    """Header stamp (and bag time) of frame t, ns."""
    return START_NS + round(t * NS / spec.fps)


def quantise(rgb: np.ndarray, encoding: str) -> np.ndarray:
    """Float RGB (H, W, 3) in [0, 1] -> the array of ``encoding`` (grey is the BT.601 luma)."""
    grey = rgb @ np.array([0.299, 0.587, 0.114])
    if encoding == "mono16":
        return np.round(grey * 65535.0).astype(np.uint16)
    if encoding == "32FC1":
        return grey.astype(np.float32)
    if encoding in ("rgb8", "bgr8"):
        out = np.round(rgb * 255.0).astype(np.uint8)
        return np.ascontiguousarray(out[..., ::-1]) if encoding == "bgr8" else out
    return np.round(grey * 255.0).astype(np.uint8)  # mono8, png, jpeg


def render_frames(spec: SynthSpec) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Frames as encoded arrays and ground truths (float32 (H, W, 2), one per frame from frame 1)."""
    rng = np.random.default_rng(spec.seed)
    build = synth_scene if spec.scene in SYNTH_SCENES else make_scene
    scene = build(spec.scene, spec.size, rng, spec.brightness)
    noise_rng = np.random.default_rng([spec.seed, 1])
    frames, gts = [], []
    for t in range(spec.frames):
        rgb = scene.render(t)
        if spec.noise > 0.0:
            rgb = np.clip(rgb + noise_rng.normal(0.0, spec.noise, rgb.shape[:2])[..., None], 0.0, 1.0)
        frames.append(quantise(rgb, spec.encoding))
        if t > 0:
            gts.append(scene.ground_truth(t).astype(np.float32))
    return frames, gts


def _image(spec: SynthSpec, arr: np.ndarray, stamp: int) -> object:
    hdr = header(stamp, FRAME_ID)
    if spec.encoding in COMPRESSED_ENCODINGS:
        ok, buf = cv2.imencode(".png" if spec.encoding == "png" else ".jpg", arr)
        if not ok:
            raise BagError(f"OpenCV could not encode a {spec.encoding} frame")
        return compressed_message(hdr, spec.encoding, np.asarray(buf, np.uint8).ravel())
    return image_message(hdr, array_to_image_fields(arr, spec.encoding))


def write_synth_bag(out: str | Path, spec: SynthSpec) -> Path:
    """Render ``spec`` and write the bag folder ``out`` (must not exist). Returns the folder.

    Written to a sibling temporary folder and renamed at the end, so a failure leaves nothing behind.
    """
    out = Path(out)
    if out.exists():
        raise BagError(f"{out} exists already; choose a new output folder")
    frames, gts = render_frames(spec)
    tmp = out.with_name(f".{out.name}.partial")
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        with BagWriter(tmp, spec.storage) as bag:
            bag.add_topic(spec.image_topic, COMPRESSED if spec.encoding in COMPRESSED_ENCODINGS else IMAGE)
            bag.add_topic(GT_TOPIC, IMAGE)
            for t, arr in enumerate(frames):
                stamp = frame_stamp(spec, t)
                bag.write(spec.image_topic, stamp, _image(spec, arr, stamp))
                if t > 0:
                    gt = image_message(header(stamp, FRAME_ID), array_to_image_fields(gts[t - 1], "32FC2"))
                    bag.write(GT_TOPIC, stamp, gt)
        _rename_files(tmp, out.name)
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


def _rename_files(folder: Path, name: str) -> None:
    """Give the storage file the final bag name (rosbags names it after the folder) and fix metadata."""
    meta = folder / "metadata.yaml"
    text = meta.read_text()
    for f in sorted(folder.iterdir()):
        if f.name.startswith(folder.name) and f.suffix in (".mcap", ".db3"):
            new = f.with_name(name + f.name[len(folder.name):])
            f.rename(new)
            text = text.replace(f.name, new.name)
    meta.write_text(text)
