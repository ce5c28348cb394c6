"""Large displacements with the census data term (issue 25, task cube): what the initialisation's sources see
(each frame histogram-equalised, initialise.equalised) and what the fusion's cost compares (census signatures,
fusion.cost_planes) do not move with a tone curve on frame 2, where the grey-value stage's inputs do.

Frames are rendered exactly (test_core_large.shifted_pair, test_fusion_numba.jump_scene); the tone curves are the
suite's gamma family and a smoothstep S-curve (bench/suite/photometric.py), applied to frame 2 only.
"""

from __future__ import annotations

import numpy as np
import pytest
import small_frames
from test_core_large import shifted_pair
from test_fusion_numba import candidates, jump_scene

from flow_node.core import numba_sort
from flow_node.core.fusion import cost_planes, fuse, planes
from flow_node.core.initialise import equalised, initialise
from flow_node.core.photometric import normalise_frames

CURVES = {"gamma 0.5": lambda x: x**0.5, "gamma 2": lambda x: x**2, "smoothstep": lambda x: x * x * (3 - 2 * x)}


def curved(frame: np.ndarray, curve: str) -> np.ndarray:
    return CURVES[curve](np.clip(frame.astype(np.float64), 0.0, 1.0)).astype(np.float32)


@pytest.mark.parametrize("curve", list(CURVES))
def test_equalised_frames_do_not_see_a_tone_curve(curve) -> None:
    """A frame equalised on its own is the same under a monotone tone curve up to the 8-bit quantisation
    (mean < 0.01 of the range); the per-frame affine map the census stage applies (its 2nd-98th percentiles to
    [0, 1], what DIS saw before) moves by 4-12 % of the range."""
    _, i1, _ = shifted_pair()
    changed = curved(i1, curve)
    assert np.mean(np.abs(equalised(changed) - equalised(i1))) < 0.01
    affine = normalise_frames((i1, changed))
    assert np.mean(np.abs(affine[1] - affine[0])) > 0.04
    assert equalised(i1).dtype == np.float32 and equalised(i1).shape == i1.shape


def test_numba_ranks_equal_the_reference() -> None:
    """The numba backend's ranks (numba_sort.ranks_numba) equal initialise.equalised bit for bit: a rendered frame,
    noise beyond [0, 1] on both sides (clipped), values on the quantisation's half-way points (rounded half to
    even), a flat frame and one pixel."""
    _, i1, _ = shifted_pair()
    rng = np.random.default_rng(3)
    halves = ((np.arange(i1.size) % 8191) * 0.5 / 4095).astype(np.float32).reshape(i1.shape)
    frames = (i1, rng.random(i1.shape, dtype=np.float32) * 1.4 - 0.2, halves, np.full((7, 9), 0.37, np.float32),
              i1[:1, :1])
    for frame in frames:
        out = numba_sort.ranks_numba(frame)
        assert out.dtype == np.float32 and out.shape == frame.shape
        assert np.array_equal(out, equalised(frame))
    assert len(np.unique(numba_sort.ranks_numba(i1))) > 100  # not trivially constant


@pytest.mark.parametrize("curve", list(CURVES))
def test_census_initialisation_sees_the_same_pair_under_a_tone_curve(curve) -> None:
    """With the census data term the DIS candidate of a 40 px pan moves by < 0.2 px mean under a tone curve on
    frame 2; DIS on the frames as the census stage maps them (each by its own affine map: the grey-value mode's
    sources) moves by more than 0.5 px."""
    i0, i1, _ = shifted_pair()
    changed = curved(i1, curve)
    census = small_frames.CONFIG.replace(initialisation="dis_ultrafast", photometric="census")
    grey = census.replace(photometric="normalise")
    (a,), (b,) = initialise(i0, i1, census), initialise(i0, changed, census)
    assert a.name == b.name == "dis_ultrafast" and np.mean(np.abs(a.flow - b.flow)) < 0.2
    (c,), (d,) = initialise(*normalise_frames((i0, i1)), grey), initialise(*normalise_frames((i0, changed)), grey)
    assert np.mean(np.abs(c.flow - d.flow)) > 0.5


def test_census_fusion_cost_moves_less_under_a_tone_curve() -> None:
    """The fusion of a box jumping 60 px (test_fusion_numba's candidates) on frames normalised each on its own,
    as in census mode: with census signatures as its cost the fused flow moves less under every tone curve on
    frame 2 than with grey values and their gradient, under gamma 2 by less than half as much; an affine change
    moves neither."""
    i0, i1, truth = jump_scene()
    cands, masks = candidates(truth, 3)

    def fused(frame1: np.ndarray, photometric: str) -> np.ndarray:
        return fuse(*normalise_frames((i0, frame1)), cands, masks, planes_of=cost_planes(photometric))[0]

    moved = {}
    for photometric in ("normalise", "census"):
        before = fused(i1, photometric)
        assert np.array_equal(before, fused((0.6 * i1 + 0.2).astype(np.float32), photometric))
        moved[photometric] = {curve: float(np.mean(np.hypot(*(fused(curved(i1, curve), photometric) - before))))
                              for curve in CURVES}
    assert all(moved["census"][c] < moved["normalise"][c] for c in CURVES)
    assert moved["census"]["gamma 2"] < 0.5 * moved["normalise"]["gamma 2"]


def test_cost_planes_of_each_mode() -> None:
    """Grey-value modes keep the brightness and gradient planes (their fusion unchanged); census compares the 8
    signature channels, with the level's EPS floor where it is above census.CENSUS's EPS."""
    i0, _, _ = jump_scene()
    assert cost_planes("normalise") is planes and cost_planes("local_contrast") is planes
    sig = cost_planes("census")(i0)
    assert sig.shape == i0.shape + (8,) and sig.dtype == np.float32
    floor = cost_planes("census", eps=0.2)(i0)
    assert np.abs(floor).mean() < 0.5 * np.abs(sig).mean()  # a larger EPS damps the signature
    assert np.array_equal(cost_planes("census", eps=0.001)(i0), sig)  # below the default: the default
