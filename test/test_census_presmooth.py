"""FlowConfig.census_presmooth (task presm): the census stage presmooths both frames of every pair by it, whatever
their quantisation (coarse pairs keep at least QUANT_SIGMA), each colour channel alike, and the noise floor's
gains describe the blur actually applied (photometric.frame_maps / normalise_frames, census_noise.pair_noise)."""

from __future__ import annotations

import numpy as np
import pytest
from synth import isoluminant_pair, texture

from bench.suite.synthetic import bit_depth
from flow_node.core.api import FlowEstimator
from flow_node.core.backends import NUMPY
from flow_node.core.census_noise import pair_noise
from flow_node.core.colour import channel_maps, normalise_channel_pair
from flow_node.core.config import FlowConfig
from flow_node.core.engine import colour_stage, photometric_stage
from flow_node.core.metrics import aee
from flow_node.core.photometric import (
    QUANT_SIGMA,
    affine_normalised,
    frame_key,
    frame_map,
    frame_maps,
    sorted_sample,
    stage,
)

CENSUS_RT = FlowConfig.preset("realtime").replace(threads=1, census_presmooth=0.0)  # today's rule


def quantised(img: np.ndarray, bits: int = 8, levels: float | None = None) -> np.ndarray:
    """img in [0, 1] to ``bits`` bit and back, float32 (``levels``: the texture first scaled to span that many
    grey levels of the encoding, a low-range frame)."""
    top = 2**bits - 1
    img = img if levels is None else 0.3 + img * levels / top
    return (np.clip(np.rint(img * top), 0, top) / top).astype(np.float32)


def clean_pair() -> tuple[np.ndarray, np.ndarray]:
    """A 12-bit textured pair (a 1 px shift): fine quantisation, no presmoothing today."""
    tex = texture(72, 97, seed=8).image
    return quantised(tex[:, 1:], 12), quantised(tex[:, :-1], 12)


def test_the_field_presmooths_a_finely_quantised_pair_and_the_floor_follows() -> None:
    f0, f1 = clean_pair()
    samples = sorted_sample(f0), sorted_sample(f1)
    assert frame_maps(samples)[1] == 0.0  # today: not presmoothed
    maps = frame_maps(samples, presmooth=0.7)
    assert maps[1] == 0.7
    (n0, n1), _ = stage(f0, f1, "census", maps=maps)  # the maps carry the blur: the stage takes it from them
    np.testing.assert_array_equal(stage(f0, f1, "census", samples=samples, maps=maps)[0][1], n1)
    for img, s, n in ((f0, samples[0], n0), (f1, samples[1], n1)):
        m = frame_map(s)
        np.testing.assert_array_equal(n, affine_normalised(img, *m, 1.0, 0.7))
        assert np.abs(n - affine_normalised(img, *m, 1.0, 0.0)).max() > 1e-3
    # the noise is measured before the blur (as without it) and the blur handed on is the one applied
    plain = pair_noise((f0, f1), frame_maps(samples), 1.0, stage(f0, f1, "census")[0])
    smooth = pair_noise((f0, f1), maps, 1.0, (n0, n1))
    assert plain.blur == 0.0 and smooth.blur == 0.7
    assert smooth.sigma == plain.sigma and smooth.frames == plain.frames
    # a stream's frame key tells the two normalised frames apart
    assert frame_key(maps, 1, 1.0) != frame_key(frame_maps(samples), 1, 1.0)


@pytest.mark.parametrize(("presmooth", "blur"), [(0.0, QUANT_SIGMA), (0.5, QUANT_SIGMA), (1.5, 1.5)])
def test_a_coarse_pair_keeps_at_least_quant_sigma(presmooth: float, blur: float) -> None:
    tex = texture(64, 80, seed=3).image
    f0, f1 = quantised(tex[:, 1:], levels=40.0), quantised(tex[:, :-1], levels=40.0)  # 40 grey levels: coarse
    maps = frame_maps((sorted_sample(f0), sorted_sample(f1)), presmooth=presmooth)
    assert maps[1] == blur
    (n0, _), _ = stage(f0, f1, "census", maps=maps)
    np.testing.assert_array_equal(n0, affine_normalised(f0, *maps[0][0], 1.0, blur))
    if presmooth == 0.0:  # without maps the stage takes them of the frames, with no presmooth of its own
        np.testing.assert_array_equal(stage(f0, f1, "census")[0][0], n0)


def test_the_engine_stage_blurs_by_the_field_grey_and_colour() -> None:
    f0, f1 = clean_pair()
    for cfg, blur in ((CENSUS_RT, 0.0), (CENSUS_RT.replace(census_presmooth=0.7), 0.7)):
        (n0, _), judged = photometric_stage(f0, f1, cfg, NUMPY)
        assert judged.maps is not None and judged.maps[1] == blur
        assert judged.noise is not None and judged.noise.blur == blur
        np.testing.assert_array_equal(n0, affine_normalised(f0, *judged.maps[0][0], 1.0, blur))
    c0, c1, _ = isoluminant_pair(3, 72, 96)
    planes = tuple(np.moveaxis(quantised(c, 12), -1, 0) for c in (c0, c1))
    cfg = CENSUS_RT.replace(census_presmooth=0.7, colour="channels")
    colour = colour_stage(planes[0].shape[1:], planes, cfg)
    assert colour is not None
    assert [m[1] for m in colour.maps] == [0.7] * 3 and colour.raw == planes
    np.testing.assert_array_equal(colour.normalised[0],
                                  normalise_channel_pair(*planes, maps=channel_maps(*planes, presmooth=0.7))[0])
    assert np.abs(colour.normalised[0] - normalise_channel_pair(*planes)[0]).max() > 1e-3
    grey = [p.mean(axis=0).astype(np.float32) for p in planes]
    _, judged = photometric_stage(grey[0], grey[1], cfg, NUMPY, colour=colour)
    assert judged.noise is not None and judged.noise.blur == 0.7  # the channels' floor, for their blur


def test_realtime_reads_a_10_bit_pair_within_10_percent_of_its_8_bit_version() -> None:
    """The suite's bit-depth target on one of its tune pairs (bench.suite.synthetic.bit_depth, the 320x240 band-4
    rotation): its 8-bit version is coarsely quantised and was presmoothed, its 10-bit one was not, and realtime
    read the 10-bit pair 1.11x its 8-bit AEE; with realtime's census_presmooth both are blurred (task presm)."""
    pairs = {s.name: s for s in bit_depth("tune", False) if s.name.startswith("s1_rotation/band4_")}
    cfg = FlowConfig.preset("realtime").replace(threads=1)
    assert cfg.census_presmooth > 0

    def ratio(c: FlowConfig) -> float:
        e8, e10 = (aee(FlowEstimator(c).estimate(s.f0, s.f1).flow, s.gt)
                   for s in (pairs["s1_rotation/band4_8bit"], pairs["s1_rotation/band4_10bit"]))
        return e10 / e8

    assert ratio(cfg) < 1.1
    assert ratio(cfg.replace(census_presmooth=0.0)) > 1.1  # today's rule: the deeper pair unsmoothed, the miss
