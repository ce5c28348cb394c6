"""The photometric stage of the engine: what the solver sees of a pair's intensities, and how well the
result explains them.

:func:`stage` runs once per pair, before the pyramid (docs/design.md, "Engine stages"). Its modes
(``PHOTOMETRIC``, the FlowConfig field ``photometric``):

* ``none``: the grey images as they come ([0, 1] by the encoding's maximum).
* ``normalise``: a global exposure change (gain and offset of frame 1 against frame 0, from matched
  percentiles, see :func:`exposure_change`) is undone, then one affine map for the pair takes its robust
  range -- the frames' mean 2nd and 98th percentiles -- to [0, 1] (coarsely quantised content: see
  :func:`normalise_pair`); a pair with a detected exposure change is then normalised locally
  (``local_contrast``), since the global fit is ~1 % off and the L1 data term reads that as motion. The
  weights then mean the same thing for 8-, 10-, 12- and 16-bit and low-contrast input (they act on contrast, not on
  encoding units). Percentiles, not min/max, so a few hot pixels or a saturated highlight do not set the
  scale; they are taken on a strided subsample (every ``STRIDE``-th pixel in each direction). One map for
  both frames, not one per frame: the frames' content differs (motion at the border), and a per-frame map
  would turn that into a brightness difference, i.e. flow error.
* ``density``: both frames multiplied by one gain, 1 / the pair's robust range (the ``normalise`` range,
  quantised content treated the same way), nothing subtracted and no exposure change undone: the intensity
  is a density whose total may change only by the motion's divergence, and a gain is the one map that
  keeps the continuity equation (the mass-preservation data term, FlowConfig.constraint).
* ``local_contrast``: ``normalise``, then each frame divided by its local contrast (:func:`local_contrast`):
  invariant to gain and offset without estimating them, so also to vignetting and local exposure changes.
* ``structure_texture``: ``normalise``, then the texture part of Wedel et al.'s structure-texture
  decomposition (TV-L1, DAGM 2009): I - STRUCTURE_WEIGHT * S(I), with S the ROF (TV-L2) denoising of I
  (Chambolle's projection, ``ROF_ITERATIONS`` steps, weight ``ROF_THETA``), renormalised. It also removes smooth
  illumination changes (shading, vignetting), at the price of some signal on smooth image regions.

The stage also hands back the pair a flow is judged on (the ``normalise`` pair in every mode but ``census``,
which judges its own), and the engine judges it by census signatures whatever the data term
(census.reliability, on :func:`reliability_stride`'s grid): the fraction of pixels the flow does not explain.
A flow that matches the frames leaves only occlusions and noise: at most 0.15 on the 8 Middlebury pairs with
``realtime`` and ``fastest``; garbage leaves most pixels unexplained (0.7 and more for a zero flow or two
unrelated frames). The node WARNs above UNRELIABLE (docs/node.md).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import cv2
import numpy as np

from .operators import div, grad

PHOTOMETRIC = ("census", "normalise", "local_contrast", "structure_texture", "density", "none")
MASS_PHOTOMETRIC = ("density", "none")  # the modes that keep the continuity equation (constraint "mass")
SIGNATURE_MODES = ("census",)  # modes whose data term compares census signatures (census.py), not grey values
PERCENTILES = (2.0, 98.0)
STRIDE = 3
MIN_SPAN = 1e-6  # a pair whose robust range is below this (flat) is only shifted, not scaled
EXPOSURE_QUANTILES = np.arange(5.0, 96.0, 5.0)
EXPOSURE_DEAD_ZONE = 0.1  # |gain - 1| below which frame 1 is left alone (see exposure_change)
STEP_REF = 0.01  # quantisation step (of the pair's range) up to which the data term is left as it is
QUANT_SIGMA = 1.0  # px: presmoothing of coarsely quantised pairs (turns their staircases back into ramps)
CLIP_MARGIN = 0.01  # quantiles this close to the encoding's 0 or 1 may be clipped: not used for the fit
LOCAL_SIGMA = 4.0  # px: the window of the local contrast normalisation
LOCAL_EPS = 0.02  # of the pair's range: local contrast below this is not amplified (noise in flat areas)
LOCAL_GAIN = 0.08  # output scale: the same alpha suits it and a normalised frame (measured on the suite)
STRUCTURE_WEIGHT = 0.95
ROF_THETA = 0.125
ROF_ITERATIONS = 30
RELIABILITY_STRIDE = 2  # the finest sampling of reliability(); coarser on large frames (reliability_stride)
RELIABILITY_SAMPLES = 20_000  # about this many sampled pixels are enough for a fraction (binomial: +-0.35 % at 1 sigma)
UNRELIABLE = 0.3  # unexplained fraction above which the node WARNs (module doc; docs/engine.md, "The judge")


def subsample(img: np.ndarray) -> np.ndarray:
    """Every STRIDE-th pixel of img (H, W) in each direction (all of a small image): a view."""
    return img[::STRIDE, ::STRIDE] if min(img.shape) > 4 * STRIDE else img


def sorted_sample(img: np.ndarray) -> np.ndarray:
    """:func:`subsample` of img (H, W), sorted, flattened (the numba backend's ``sample`` gives the same array:
    numba_sort.py)."""
    return np.sort(subsample(img), axis=None)


# both frames' sorted samples (:func:`sorted_sample`), frame 0's first
Samples = tuple[np.ndarray, np.ndarray]


def frame_samples(i0: np.ndarray, i1: np.ndarray, known0: np.ndarray | None = None,
                  sample: Callable[[np.ndarray], np.ndarray] | None = None) -> Samples:
    """Both frames' :func:`sorted_sample` (or ``sample``'s, a backend's: the same arrays), frame 0's taken from
    ``known0`` when given (a stream's previous pair sorted it as its frame 1)."""
    sample = sorted_sample if sample is None else sample
    return sample(i0) if known0 is None else known0, sample(i1)


def quantiles(ordered: np.ndarray, percents: np.ndarray | tuple[float, ...]) -> np.ndarray:
    """Nearest-rank percentiles (in %) of a sorted sample, float64."""
    idx = np.rint(np.asarray(percents) / 100.0 * (ordered.size - 1)).astype(np.int64)
    return ordered[idx].astype(np.float64)


def exposure_change(s0: np.ndarray, s1: np.ndarray) -> tuple[float, float]:
    """(gain, offset) with gain * I1 + offset ~ I0 in distribution, from the sorted samples s0, s1 of the
    frames (:func:`sorted_sample`): a least-squares line through their matched 5th..95th percentiles,
    leaving out quantiles that may be clipped. Returns (1, 0) when |gain - 1| < EXPOSURE_DEAD_ZONE: a pair
    without an exposure change differs in content (motion at the border, small images), which moves the
    percentiles -- measured: gains 0.95-1.05 with offsets of a few grey levels on unchanged pairs -- and
    must not read as an exposure change (a false correction is a brightness difference, i.e. flow error).
    Auto-exposure steps are larger (0.75-1.33)."""
    q0, q1 = quantiles(s0, EXPOSURE_QUANTILES), quantiles(s1, EXPOSURE_QUANTILES)
    ok = (np.minimum(q0, q1) > CLIP_MARGIN) & (np.maximum(q0, q1) < 1.0 - CLIP_MARGIN)
    if ok.sum() < 3 or np.ptp(q1[ok]) <= MIN_SPAN:
        return 1.0, 0.0
    gain, offset = line_fit(q1[ok], q0[ok])
    if abs(gain - 1.0) < EXPOSURE_DEAD_ZONE:
        return 1.0, 0.0
    return float(gain), float(offset)


def line_fit(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Least-squares (slope, intercept) of y ~ slope * x + intercept in closed form (np.polyfit's degree-1
    answer without its SVD: ~30x cheaper on the 19 quantiles here). x must not be constant."""
    xm, ym = x.mean(), y.mean()
    slope = float(np.dot(x - xm, y - ym) / np.dot(x - xm, x - xm))
    return slope, float(ym - slope * xm)


def quantisation_step(ordered: np.ndarray) -> float:
    """The smallest positive difference between the grey values of a sorted sample: the encoding's step for
    integer input (1/255 for 8 bit, 1/65535 for 10-bit content in mono16), ~0 for continuous values."""
    gaps = np.diff(ordered)
    gaps = gaps[gaps > 0]
    return float(gaps.min()) if gaps.size else 0.0


def compares_signatures(mode: str) -> bool:
    """Whether the data term of photometric ``mode`` compares census signatures (census.py) instead of grey
    values: the refinement then builds the census quadratic form per warp and reliability judges signatures."""
    return mode in SIGNATURE_MODES


def affine_normalised(img: np.ndarray, lo: float, hi: float, step: float, noise_gain: float,
                      presmooth: float | None = None) -> np.ndarray:
    """img mapped by (img - lo) / (hi - lo), or to [0, STEP_REF / rel] with rel = step * noise_gain / (hi - lo)
    when rel > STEP_REF, then presmoothed by QUANT_SIGMA (unless noise_gain < 1); see :func:`normalise_pair`.
    ``presmooth``: the Gaussian (px; 0: none) to presmooth by, decided by the caller (:func:`frame_maps`' blur);
    None: as above."""
    rel = relative_step(lo, hi, step, noise_gain)
    span = hi - lo if hi - lo > MIN_SPAN else 1.0
    scale = np.float32(min(1.0, STEP_REF / rel) / span if rel > 0 else 1.0 / span)
    out = (img - np.float32(lo)) * scale
    if presmooth is None:  # else the pyramid's anti-alias blur (>= 1.4 px) does it
        presmooth = QUANT_SIGMA if rel > STEP_REF and noise_gain >= 1.0 else 0.0
    if presmooth > 0:
        out = cv2.GaussianBlur(out, (0, 0), float(presmooth), borderType=cv2.BORDER_REFLECT)
    return out


def relative_step(lo: float, hi: float, step: float, noise_gain: float) -> float:
    """rel of :func:`affine_normalised`: the quantisation step (after the noise gain) over the range hi - lo."""
    return step * noise_gain / (hi - lo if hi - lo > MIN_SPAN else 1.0)


def normalise_frames(frames: tuple[np.ndarray, np.ndarray], noise_gain: float = 1.0, maps: FrameMaps | None = None,
                     n0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Both frames (H, W) float32, each by its own robust range (its 2nd and 98th percentiles mapped to [0, 1],
    coarsely quantised content's contrast shrunk as in :func:`normalise_pair`: the ``census`` mode's map; its
    data term is invariant to each frame's gain and offset, and the map gives EPS the same meaning in both
    frames), and both presmoothed by the one Gaussian ``maps`` carry (:func:`frame_maps`: QUANT_SIGMA when either's
    quantisation is coarse, FlowConfig.census_presmooth in any case, the larger of the two): the
    two signatures a census data term compares must come from the same filter (a blur is not a tone curve, so
    one frame blurred and the other not differ wherever there is texture; issue 25's low light, frame 2
    darkened 0.4x: docs/engine.md). ``maps``: the frames' :func:`frame_maps` at this ``noise_gain`` (the engine
    takes them once for this and the noise floor, census_noise.pair_noise); None: taken here of the frames'
    :func:`frame_samples` without a ``presmooth`` (a caller that wants one builds the maps). ``n0``: frame 0 already
    normalised by its map, presmoothing and noise gain (a stream's previous pair normalised it as its frame 1:
    engine.Seen, keyed by :func:`frame_key`), taken as it is."""
    (map0, map1), blur = frame_maps(frame_samples(*frames), noise_gain) if maps is None else maps
    if n0 is None:
        n0 = affine_normalised(frames[0], *map0, noise_gain, blur)
    return n0, affine_normalised(frames[1], *map1, noise_gain, blur)


# a frame's own map: (lo, hi, step), its robust range and quantisation step
FrameMap = tuple[float, float, float]
# both frames' maps and the Gaussian (px; 0: none) both are presmoothed by (:func:`frame_maps`)
FrameMaps = tuple[tuple[FrameMap, FrameMap], float]


def frame_map(ordered: np.ndarray) -> FrameMap:
    """A frame's own map from its sorted sample: its robust range (PERCENTILES) and quantisation step."""
    lo, hi = quantiles(ordered, PERCENTILES)
    return float(lo), float(hi), quantisation_step(ordered)


def frame_maps(samples: Samples, noise_gain: float = 1.0, map0: FrameMap | None = None,
               presmooth: float = 0.0) -> FrameMaps:
    """Each frame's own map from its sorted sample (:func:`frame_map`; frame 0's ``map0`` when known: a stream's
    previous pair took it of the same sample as its frame 1's), and the Gaussian (px) :func:`normalise_frames`
    presmooths both by: QUANT_SIGMA when either's quantisation step is coarse (rel > STEP_REF) and
    noise_gain >= 1, ``presmooth`` (FlowConfig.census_presmooth) whatever the quantisation and noise gain, the
    larger of the two; 0: none."""
    maps = (frame_map(samples[0]) if map0 is None else map0, frame_map(samples[1]))
    coarse = noise_gain >= 1.0 and any(relative_step(*m, noise_gain) > STEP_REF for m in maps)
    return maps, max(float(presmooth), QUANT_SIGMA if coarse else 0.0)


def frame_key(maps: FrameMaps, k: int, noise_gain: float) -> tuple[float, ...]:
    """What :func:`normalise_frames` makes of frame ``k`` depends on besides the frame: its own map, the pair's
    presmoothing and the noise gain. Two pairs that share a frame and give it equal keys normalise it to the same
    image, bit for bit (a stream's frame 1, then the next pair's frame 0: engine.Seen)."""
    (m0, m1), blur = maps
    return (*(m0, m1)[k], float(blur), noise_gain)


def normalise(i0: np.ndarray, i1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`normalise_pair` without its exposure flag."""
    return normalise_pair(i0, i1)[:2]


def normalise_pair(i0: np.ndarray, i1: np.ndarray, noise_gain: float = 1.0, pmap: PairMap | None = None,
                   n0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, bool]:
    """Both frames (H, W) float32 with frame 1's exposure matched to frame 0 (:func:`exposure_change`) and
    one affine map for the pair taking its robust range -- the frames' mean 2nd and 98th percentiles -- to
    [0, 1].

    A pair whose quantisation step is coarse against that range (rel = step / range > STEP_REF: content
    spanning fewer than ~100 grey levels) is presmoothed (QUANT_SIGMA) and mapped to [0, STEP_REF / rel]
    instead: its data term carries quantisation noise of relative size rel, and shrinking the contrast by
    the same factor keeps the balance of data term and weights (exactly for the L1 data term). The flag
    says whether an exposure change was found (and undone). ``noise_gain`` (<= 1) is how much the
    quantisation noise shrinks where the data term is evaluated (the pyramid's anti-alias blur when the
    finest solved level is coarser than the input: :func:`flow_node.core.pyramid.noise_gain`); rel is
    judged after it, and the presmoothing is left to that blur (wider than QUANT_SIGMA, it does the same
    on the level the data term lives on; both together take a low-contrast texture's signal too).
    ``pmap``: the pair's :func:`pair_map` when known (computed from :func:`frame_samples` otherwise). ``n0``:
    i0 already mapped by this very map and noise gain (a stream's previous pair mapped it as its frame 1:
    engine.Seen), taken as it is."""
    gain, offset, lo, hi, step = pair_map(frame_samples(i0, i1)) if pmap is None else pmap
    if (gain, offset) != (1.0, 0.0):
        i1 = i1 * np.float32(gain) + np.float32(offset)
    if n0 is None:
        n0 = affine_normalised(i0, lo, hi, step, noise_gain)
    return n0, affine_normalised(i1, lo, hi, step, noise_gain), (gain, offset) != (1.0, 0.0)


# what normalise_pair maps a pair by: (gain, offset, lo, hi, step), :func:`pair_map`
PairMap = tuple[float, float, float, float, float]


def pair_map(samples: Samples) -> PairMap:
    """What :func:`normalise_pair` maps a pair by, from both frames' sorted samples: frame 1's exposure change
    (gain, offset; (1, 0) for none) and the pair's robust range (lo, hi) and quantisation step (of frame 0).
    Two pairs with equal maps (and noise gains) map an image they share to the same normalised image."""
    s0, s1 = samples
    gain, offset = exposure_change(s0, s1)
    if (gain, offset) != (1.0, 0.0):
        s1 = s1 * gain + offset
    lo, hi = 0.5 * (quantiles(s0, PERCENTILES) + quantiles(s1, PERCENTILES))
    return gain, offset, float(lo), float(hi), quantisation_step(s0)


def density_pair(i0: np.ndarray, i1: np.ndarray, noise_gain: float = 1.0, samples: Samples | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Both frames (H, W) float32 times one gain, 1 / the pair's robust range (mean 2nd-98th percentiles),
    coarse quantisation treated as in :func:`normalise_pair`: the ``density`` mode, no offset (see module doc).
    ``samples``: as for :func:`normalise_pair`."""
    s0, s1 = frame_samples(i0, i1) if samples is None else samples
    lo, hi = 0.5 * (quantiles(s0, PERCENTILES) + quantiles(s1, PERCENTILES))
    step = quantisation_step(s0)
    n0, n1 = (affine_normalised(img, 0.0, hi - lo, step, noise_gain) for img in (i0, i1))
    return n0, n1


def rof_structure(img: np.ndarray, theta: float = ROF_THETA, iterations: int = ROF_ITERATIONS) -> np.ndarray:
    """ROF denoising argmin_S |grad S|_1 + |S - img|^2 / (2 theta) by Chambolle's dual projection
    (step 1/4, isotropic), the structure part of the decomposition. img (H, W) -> (H, W) float32."""
    p = np.zeros((2,) + img.shape, np.float32)
    step = np.float32(0.25)
    for _ in range(iterations):
        g = grad(div(p) - img / np.float32(theta))
        p = (p + step * g) / (1.0 + step * np.sqrt(g[0] ** 2 + g[1] ** 2))
    return (img - theta * div(p)).astype(np.float32)


def texture_part(img: np.ndarray) -> np.ndarray:
    """The texture part I - STRUCTURE_WEIGHT * rof_structure(I) of a frame, (H, W) float32."""
    return (img - STRUCTURE_WEIGHT * rof_structure(img)).astype(np.float32)


def local_contrast(img: np.ndarray) -> np.ndarray:
    """(I - G*I) / (sqrt(G*(I - G*I)^2) + LOCAL_EPS) * LOCAL_GAIN with G a Gaussian of LOCAL_SIGMA px:
    invariant to a gain and offset of the frame (exactly, where the local contrast is well above
    LOCAL_EPS), and, being a shift-invariant local operator, it commutes with the motion. (H, W) float32."""
    blur = lambda x: cv2.GaussianBlur(x, (0, 0), LOCAL_SIGMA, borderType=cv2.BORDER_REFLECT)  # noqa: E731
    detail = img - blur(img)
    return (detail * (LOCAL_GAIN / (np.sqrt(blur(detail * detail)) + LOCAL_EPS))).astype(np.float32)


def preprocess(i0: np.ndarray, i1: np.ndarray, mode: str) -> tuple[np.ndarray, np.ndarray]:
    """The photometric stage: both frames (H, W) float32 as the solver should see them (see module doc)."""
    return stage(i0, i1, mode)[0]


def stage(i0: np.ndarray, i1: np.ndarray, mode: str, noise_gain: float = 1.0, samples: Samples | None = None,
          pmap: PairMap | None = None, n0: np.ndarray | None = None, maps: FrameMaps | None = None
          ) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """The engine's one call: (what the solver sees, the normalised pair census.reliability judges).
    The second is the ``normalise`` result in every mode but ``census``; ``census`` normalises each frame on its
    own (:func:`normalise_frames`, no exposure detection: its data term needs none; both presmoothed alike) and
    returns that pair twice.
    ``noise_gain``: see :func:`normalise_pair`. ``samples``: both frames' :func:`sorted_sample` when known (a
    stream knows its new pair's first frame's from the previous pair: temporal.Prior), computed here otherwise;
    every mode's ranges come from them; ``pmap``: their :func:`pair_map` when known (every mode but ``census``
    uses it); ``n0``: i0 normalised by that map when known (:func:`normalise_pair`; ``census``: by its own map,
    :func:`normalise_frames`); ``maps``: ``census`` only, their :func:`frame_maps` at this ``noise_gain``, which
    carry the presmoothing (FlowConfig.census_presmooth: the engine builds them with it); None: taken here of
    the samples, without a ``presmooth``."""
    s0, s1 = frame_samples(i0, i1) if samples is None else samples
    if compares_signatures(mode):
        pair = normalise_frames((i0, i1), noise_gain, frame_maps((s0, s1), noise_gain) if maps is None else maps, n0)
        return pair, pair
    n0, n1, exposure_changed = normalise_pair(i0, i1, noise_gain, pair_map((s0, s1)) if pmap is None else pmap, n0)
    if mode == "density":
        return density_pair(i0, i1, noise_gain, (s0, s1)), (n0, n1)
    if mode == "none":
        return (i0, i1), (n0, n1)
    if mode == "normalise" and exposure_changed:
        # the global fit leaves a residual gain of ~1 % (content differences move the percentiles), which
        # the L1 data term reads as motion; the local normalisation is invariant to gain and offset outright
        return (local_contrast(n0), local_contrast(n1)), (n0, n1)
    return solver_images(n0, n1, mode), (n0, n1)


def solver_images(n0: np.ndarray, n1: np.ndarray, mode: str) -> tuple[np.ndarray, np.ndarray]:
    """The solver's images of a normalised pair for ``mode`` (not ``none``)."""
    if mode == "local_contrast":
        return local_contrast(n0), local_contrast(n1)
    if mode == "structure_texture":
        return normalise(texture_part(n0), texture_part(n1))
    return n0, n1


# reliability(i0, i1, flow[, samples=]) -> unexplained fraction: census.reliability or a backend's kernel
# (``samples``: about how many pixels its grid has, :func:`reliability_stride`)
Reliability = Callable[..., float]


def reliability_stride(h: int, w: int, samples: int | None = None) -> int:
    """The reliability figure's grid on an (h, w) frame: RELIABILITY_STRIDE, or coarser so that the grid has
    about ``samples`` points (None: RELIABILITY_SAMPLES, read at the call, the one place every reliability
    function's default comes from; 640x480 at stride 4, 19,200 points); census.reliability samples every
    SAMPLE_SPACING-th of them. A stream's refined prediction is checked on fewer (FlowConfig.stream_check_samples)."""
    return max(RELIABILITY_STRIDE, round(math.sqrt(h * w / (samples or RELIABILITY_SAMPLES))))
