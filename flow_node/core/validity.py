"""The validity mask: pixels that carry no data (a wiper, the robot's own body, dead pixels, a dirty lens).

A mask marks each pixel of a frame valid (nonzero / True) or invalid (zero / False), as OpenCV's mask
arguments do. A caller gives one mask for both frames (a fixed occluder: the robot's body, dead pixels) or
one per frame (a moving one: a wiper). What the engine does with it:

* before the photometric stage, invalid pixels are filled from their valid neighbours (:func:`fill_invalid`):
  their values are garbage, and the pyramid's blur, the warp's B-spline and the initialisation would
  otherwise spread them into the valid pixels around;
* every pyramid level gets both masks (:func:`mask_levels`: the level's blur and resampling of the mask, the
  fraction m in [0, 1] of a level pixel that comes from valid input pixels);
* on every warp the data term is weighted per pixel (:func:`data_weight`): trust(m0(x)) * trust(m1(x + v0))
  with frame 1's mask sampled bilinearly and trust(m) = clip(2 m - 1, 0, 1) (:func:`trust`): 0 where frame 0
  is invalid at x or frame 1 at x + v0 (or where half of what a level pixel or a sample is made of is), 1
  where all of it is valid. A binary cut at m = 1 instead leaves no data at all on the coarse levels of a
  frame with scattered dead pixels (2 % of the pixels: every coarse pixel has one).
  The weight enters the data term of every model (:func:`flow_node.core.models.weight_data`), so masked
  pixels get their flow from the regulariser alone; each level starts them from their neighbours' flow
  (:func:`fill_flow`), since the regulariser alone propagates it only slowly.

Masks are (H, W) bool here; :func:`as_masks` validates what a caller passes.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from .errors import InputError
from .operators import warp_maps

VALID_LEVEL = 0.999  # a shrunk binary mask (the stream's input_scale) is valid where its area mean reaches this
FILL_SIGMA0 = 1.0  # px: first blur of the fill; doubled until every invalid pixel has valid neighbours
FILL_DIRECT = 2.0  # px: blurs wider than this run on a shrunk image (_blur)

# one mask for both frames, or one per frame
MaskInput = np.ndarray | Sequence[np.ndarray] | None


def as_mask(mask: object, shape: tuple[int, int], name: str = "mask") -> np.ndarray:
    """Validate one mask for frames of ``shape`` (H, W): a bool or integer array (H, W) or (H, W, 1),
    nonzero = valid. Returns (H, W) bool; InputError naming the problem (type, dtype, size, nothing valid)."""
    if not isinstance(mask, np.ndarray):
        raise InputError(f"{name}: expected a numpy array, got {type(mask).__name__}")
    if mask.ndim == 3 and mask.shape[2] == 1:
        mask = mask[:, :, 0]
    if mask.dtype != np.bool_ and not np.issubdtype(mask.dtype, np.integer):
        raise InputError(f"{name}: expected a bool or integer array (nonzero = valid), got dtype {mask.dtype}")
    if mask.shape != tuple(shape):
        raise InputError(f"{name}: expected shape {tuple(shape)} (the frames' H x W), got {mask.shape}")
    valid = mask.astype(bool, copy=False)
    if not valid.any():
        raise InputError(f"{name}: every pixel is marked invalid; nothing to estimate flow from")
    return valid


def as_masks(mask: MaskInput, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray] | None:
    """A caller's mask argument as (valid0, valid1), (H, W) bool each: one array applies to both frames, a
    pair (list or tuple of two arrays) gives frame 0's and frame 1's. None stays None (all valid)."""
    if mask is None:
        return None
    if isinstance(mask, (list, tuple)):
        if len(mask) != 2:
            raise InputError(f"mask: expected one array or a pair (mask0, mask1), got {len(mask)} items")
        return as_mask(mask[0], shape, "mask0"), as_mask(mask[1], shape, "mask1")
    valid = as_mask(mask, shape)
    return valid, valid


def fill_invalid(img: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """img (H, W) float32 with its invalid pixels replaced by normalised convolution of the valid ones:
    blur(img * valid) / blur(valid) with a Gaussian of FILL_SIGMA0 px, doubled until every invalid pixel is
    reached (smooth, a few blurs per frame). Valid pixels are unchanged. -> float32 (H, W), a new array."""
    out = np.array(img, dtype=np.float32, copy=True)
    done = valid.copy()
    weight = valid.astype(np.float32)
    masked = out * weight
    sigma = FILL_SIGMA0
    while not done.all():
        if sigma > max(out.shape):  # beyond the image's size: what is still unreached gets the valid mean
            out[~done] = float(out[valid].mean()) if valid.any() else 0.0
            break
        num, den = _blur(masked, sigma), _blur(weight, sigma)
        take = ~done & (den > 1e-3)
        out[take] = num[take] / den[take]
        done |= take
        sigma *= 2.0
    return out


def _blur(img: np.ndarray, sigma: float) -> np.ndarray:
    """A Gaussian blur of sigma px (reflected border); beyond FILL_DIRECT px computed on the image shrunk by
    sigma / FILL_DIRECT (area), blurred by FILL_DIRECT and enlarged back (bilinear): the fill only needs a
    smooth average, and a direct blur's cost grows with sigma (measured: the fill of a 26 px wiper band took
    most of realtime's time with a mask)."""
    if sigma <= FILL_DIRECT:
        return cv2.GaussianBlur(img, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    h, w = img.shape
    factor = sigma / FILL_DIRECT
    small = cv2.resize(img, (max(1, round(w / factor)), max(1, round(h / factor))), interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (0, 0), FILL_DIRECT, borderType=cv2.BORDER_REFLECT)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)


def mask_levels(valid: np.ndarray, levels: list[np.ndarray]) -> list[np.ndarray]:
    """A mask (H, W) bool on every level of a pyramid, finest first, float32 in [0, 1]: ``levels`` is the
    mask's pyramid built by the caller with the images' blur (the finest level replaced by the mask itself,
    exactly 0/1)."""
    return [valid.astype(np.float32)] + [np.clip(m, 0.0, 1.0).astype(np.float32) for m in levels[1:]]


def trust(m: np.ndarray) -> np.ndarray:
    """The data weight of a pixel a fraction m (float32 array in [0, 1]) of which is valid: clip(2 m - 1, 0, 1)."""
    return np.clip(2.0 * m - 1.0, 0.0, 1.0).astype(np.float32)


def data_weight(valid0: np.ndarray, valid1: np.ndarray, flow0: np.ndarray) -> np.ndarray:
    """The data term's per-pixel weight of one warp around flow0 (2, h, w) px on a level whose masks are
    valid0, valid1 (h, w) float32 in [0, 1] (:func:`mask_levels`): trust(valid0(x)) * trust(valid1 sampled
    bilinearly at x + flow0(x)) (outside the image frame 1 counts as invalid). -> (h, w) float32 in [0, 1]."""
    map_x, map_y, _ = warp_maps(flow0)
    sampled = cv2.remap(valid1, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    return trust(valid0) * trust(sampled)


def fill_flow(flow: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """flow (2, h, w) with each component filled (:func:`fill_invalid`) where the data weight (h, w) is 0:
    the start of a warp on a level with a mask. The regulariser alone moves a data-free pixel's flow only by
    about one pixel of propagation per iteration; a few warps of a few iterations leave a large hole's
    interior near its initial value, so that value is the neighbours' flow, not the coarser level's.
    Unchanged when no pixel has data."""
    has_data = weight > 0
    if has_data.all() or not has_data.any():
        return flow
    return np.stack([fill_invalid(comp, has_data) for comp in flow])
