"""Colour input for the census data term (FlowConfig ``colour = channels``; numpy reference census.census_form,
numba: numba_census.census_form_numba, both for C channels).

With grey input the census data term compares one signature per pixel, K = 8 channels (census.py). A colour
frame has three grey images, each with its own texture (an edge between two colours of one brightness is
invisible in luma), and a camera changes each of them on its own: white balance is a gain per channel, and
tone curves are applied per channel. So each colour channel is normalised on its own (per frame, as the
census mode does with grey: :func:`normalise_channel_pair`), its signature taken as for grey, and the C x K
signatures stacked into one data term:

    rho_{c,k}(v) = a_{c,k} . v + c_{c,k},    data = 1/C sum_c sum_k rho_{c,k}^2 (L2)  or  |rho_{c,k}| (L1)

collapsed into the same per-pixel quadratic form (5, H, W) the solver's data prox takes (census.census_form:
grey input is its case C = 1, with the L1 weights of census.py). Frame 1's channels are sampled at x + v0
directly (one interpolation per channel, census.warped_frames), as the grey census term's one. The 1/C keeps
the data term's weight against the regulariser that of grey input (alpha means the same for both).
Invariant per channel to what the grey signature is invariant to,
hence to white balance and to per-channel tone curves. A pixel whose x + v0 leaves the image has no data
term. Everything but the data term -- initialisation, fusion,
reliability, confidence -- stays on the grey (luma) frames.

Costs: per level C prefilters and signatures of frame 0; per warp C samples of frame 1, C signatures and
C x K channels in the form (measured: docs/engine.md, "The census data term", colour).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .photometric import FrameMaps, frame_maps, frame_samples, normalise_frames

COLOUR_MODES = ("grey", "channels")  # the FlowConfig field ``colour``: luma only, or every channel (census)

# each colour channel's photometric.frame_maps, channel 0 first (:func:`channel_maps`)
ChannelMaps = tuple[FrameMaps, ...]


def channel_maps(frame0: np.ndarray, frame1: np.ndarray, noise_gain: float = 1.0, presmooth: float = 0.0,
                 sample: Callable[[np.ndarray], np.ndarray] | None = None) -> ChannelMaps:
    """Per channel c of both frames (C, H, W), photometric.frame_maps of the two frames' channel c at ``noise_gain``:
    their own maps and the blur both get (QUANT_SIGMA when either's quantisation is coarse, ``presmooth`` px --
    FlowConfig.census_presmooth -- in any case, the larger), from their sorted samples (photometric.frame_samples,
    by ``sample``: a backend's, the same arrays). Taken once per pair: the normalisation
    (:func:`normalise_channel_pair`) and the noise floor (census_noise.channel_noise) share them."""
    return tuple(frame_maps(frame_samples(c0, c1, sample=sample), noise_gain, presmooth=presmooth)
                 for c0, c1 in zip(frame0, frame1, strict=True))


def normalise_channel_pair(frame0: np.ndarray, frame1: np.ndarray, noise_gain: float = 1.0,
                           maps: ChannelMaps | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Both frames' channels (C, H, W) float32, each by its own robust range (a per-channel gain -- white
    balance -- and offset are undone exactly), channel c of both frames presmoothed alike
    (photometric.normalise_frames, by channel c's blur): (C, H, W) each. ``maps``: :func:`channel_maps` of the
    frames at this ``noise_gain`` (which carry FlowConfig.census_presmooth); None: taken here without a presmooth."""
    maps = channel_maps(frame0, frame1, noise_gain) if maps is None else maps
    pairs = [normalise_frames((c0, c1), noise_gain, m) for c0, c1, m in zip(frame0, frame1, maps, strict=True)]
    return tuple(np.stack([p[k] for p in pairs]).astype(np.float32, copy=False) for k in (0, 1))


@dataclass(frozen=True)
class NormalisedChannels:
    """Both frames' channels (C, H, W) as they came (``raw``), normalised (``normalised``:
    :func:`normalise_channel_pair`, what the census term compares) and the per-channel maps they were normalised
    by (``maps``: :func:`channel_maps`, with the blur; the noise floor measures the channels on them,
    census_noise.channel_noise): the colour part of the photometric stage (engine.colour_stage)."""

    raw: tuple[np.ndarray, np.ndarray]
    normalised: tuple[np.ndarray, np.ndarray]
    maps: ChannelMaps


def normalised_channels(frame0: np.ndarray, frame1: np.ndarray, noise_gain: float = 1.0, presmooth: float = 0.0,
                        sample: Callable[[np.ndarray], np.ndarray] | None = None) -> NormalisedChannels:
    """The :class:`NormalisedChannels` of both frames' channels (C, H, W): each channel's samples and maps taken
    once (:func:`channel_maps`, with ``presmooth`` and ``sample``), the channels normalised on them."""
    maps = channel_maps(frame0, frame1, noise_gain, presmooth, sample)
    return NormalisedChannels((frame0, frame1), normalise_channel_pair(frame0, frame1, noise_gain, maps), maps)
