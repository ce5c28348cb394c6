"""Colour input for the census data term (FlowConfig ``colour = channels``; numpy reference, numba:
numba_census.colour_form_numba).

With grey input the census data term compares one signature per pixel, K = 8 channels (census.py). A colour
frame has three grey images, each with its own texture (an edge between two colours of one brightness is
invisible in luma), and a camera changes each of them on its own: white balance is a gain per channel, and
tone curves are applied per channel. So each colour channel is normalised on its own (per frame, as the
census mode does with grey: :func:`normalise_channels`), its signature taken as for grey, and the C x K
signatures stacked into one data term:

    rho_{c,k}(v) = a_{c,k} . v + c_{c,k},    data = 1/C sum_c sum_k rho_{c,k}^2 (L2)  or  |rho_{c,k}| (L1)

collapsed into the same per-pixel quadratic form (5, H, W) the solver's data prox takes (census.signature_form,
with the L1 weights of census.py). Frame 1's channels are sampled at x + v0 directly (one interpolation per
channel, :func:`warped_channels`), not recovered from a grey-value linearisation as the grey census term does:
the colour form needs no (a, c) of its own. The 1/C keeps the data term's weight against the regulariser that of grey
input (alpha means the same for both). Invariant per channel to what the grey signature is invariant to,
hence to white balance and to per-channel tone curves. A pixel whose x + v0 leaves the image has no data
term. Everything but the data term -- initialisation, fusion,
reliability, confidence -- stays on the grey (luma) frames.

Costs: per level C prefilters and signatures of frame 0; per warp C samples of frame 1, C signatures and
C x K channels in the form (measured: docs/engine.md, "The census data term", colour).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .census import CENSUS, CensusParams, LevelSignature, signature, signature_form
from .operators import warp_maps
from .photometric import normalise_frame
from .warping import Sample

COLOUR_MODES = ("grey", "channels")  # the FlowConfig field ``colour``: luma only, or every channel (census)


def normalise_channels(frame: np.ndarray, noise_gain: float = 1.0) -> np.ndarray:
    """Each channel of a frame (C, H, W) float32 mapped by its own robust range (photometric.normalise_frame):
    (C, H, W) float32. A per-channel gain (white balance) and offset are undone exactly."""
    return np.stack([normalise_frame(ch, noise_gain) for ch in frame]).astype(np.float32, copy=False)


def channel_signature(frames: np.ndarray, level_signature: LevelSignature, params: CensusParams = CENSUS
                      ) -> tuple[np.ndarray, np.ndarray | None]:
    """Frame 0's signatures of every channel of ``frames`` (C, H, W), stacked: (C K, H, W), and their
    gradients (2, C K, H, W) (None when ``level_signature`` -- census.level_signature or a backend's -- gives
    none: the numba form takes them itself)."""
    sigs = [level_signature(np.ascontiguousarray(ch), params) for ch in frames]
    f0 = np.concatenate([s[0] for s in sigs])
    g0 = None if sigs[0][1] is None else np.concatenate([s[1] for s in sigs], axis=1)
    return f0, g0


def warped_channels(coefs: np.ndarray, i1s: np.ndarray, v0: np.ndarray, kernel: str, sample: Sample
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Frame 1's channels sampled at x + v0 (2, H, W): (C, H, W) float32, from their interpolation
    coefficients ``coefs`` (C, H, W) (warping.Warper.coefficients, once per level) with a backend's ``sample``;
    and the mask (H, W) bool of pixels whose x + v0 leaves the image (operators.warp_maps), where the
    channels of i1s (C, H, W) themselves stand in, as in census.warped_frame."""
    map_x, map_y, inside = warp_maps(v0)
    warped = sample(coefs, map_x, map_y, kernel)
    return np.where(inside, warped, i1s).astype(np.float32, copy=False), ~inside


def colour_form(f0: np.ndarray, g0: np.ndarray | None, warped: np.ndarray, outside: np.ndarray, v0: np.ndarray,
                robust: bool, params: CensusParams = CENSUS) -> np.ndarray:
    """One warp's colour census data term: the quadratic form (5, H, W) around v0 (2, H, W) (module doc).

    f0 (C K, H, W), g0 (2, C K, H, W): :func:`channel_signature` of frame 0's channels; ``warped`` (C, H, W)
    and ``outside`` (H, W) from :func:`warped_channels`; ``robust``: the L1 data term (else L2)."""
    if g0 is None:
        raise ValueError("colour_form needs frame 0's signature gradients (census.level_signature)")
    f1 = np.concatenate([signature(w, params) for w in warped])
    form = signature_form(f0, g0, f1, outside, v0, robust, params)
    return (form * np.float32(1.0 / len(warped))).astype(np.float32)


# colour_form(f0, g0, warped, outside, v0, robust, params) -> q: colour_form or a backend's kernels
ColourForm = Callable[[np.ndarray, np.ndarray | None, np.ndarray, np.ndarray, np.ndarray, bool, CensusParams],
                      np.ndarray]
