"""The exact renderers of flow_node/bag/scenes.py used by the accuracy suite: band-limited textures, flat
areas, general affine motion. Frame 1 sampled analytically at x + gt(x) must equal frame 0, and the
ground truth must be the motion itself."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flow_node.bag.scenes import (
    FINE_MOTIONS,
    BandTexture,
    Layer,
    LinearMotion,
    Scene,
    fine_motion,
    render_grey_pair,
)
from flow_node.core.errors import ConfigError

SIZE = (64, 48)


def _scene(kind: str, seed: int, flat: bool = False) -> tuple[Scene, LinearMotion]:
    rng = np.random.default_rng(seed)
    tex = BandTexture.band(rng, 1 / 10, 1 / 3)
    if flat:
        mask = BandTexture.band(rng, 1 / 40, 1 / 20, n=8)
        tex = BandTexture(tex.freqs, tex.phases, tex.amps, tex.tint, tex.lo, tex.hi, flat=mask, flat_level=0.4)
    motion = fine_motion(kind, SIZE, rng)
    return Scene(kind, SIZE, (Layer(tex, motion),)), motion


@pytest.mark.parametrize("kind", FINE_MOTIONS)
def test_frame1_at_x_plus_flow_is_frame0(kind: str) -> None:
    scene, _ = _scene(kind, 3, flat=kind == "affine")
    i0, i1, gt = render_grey_pair(scene)
    back = scene.render(1, scene.pixel_grid() + gt) @ np.array([0.299, 0.587, 0.114])
    assert np.max(np.abs(back - i0)) < 1e-9
    # and the pair is not trivially equal: the motion changes the frame by far more than that
    assert np.mean(np.abs(i1 - i0)) > 0.01


@pytest.mark.parametrize("kind", FINE_MOTIONS)
def test_ground_truth_is_the_motion(kind: str) -> None:
    scene, motion = _scene(kind, 5)
    _, _, gt = render_grey_pair(scene)
    x = scene.pixel_grid()
    c, m, b = np.asarray(motion.center), np.asarray(motion.matrix), np.asarray(motion.offset)
    assert np.allclose(gt, c + (x - c) @ m.T + b - x, atol=1e-12)
    peak = np.max(np.linalg.norm(gt, axis=-1))
    assert 0.3 - 1e-9 <= peak <= 3.0 + 1e-9  # fine_motion's largest displacement lies in [0.3, 3] px


def test_motion_kinds_have_their_structure() -> None:
    rng = np.random.default_rng(0)
    rot = np.asarray(fine_motion("rotation", SIZE, rng).matrix)
    assert np.allclose(rot @ rot.T, np.eye(2), atol=1e-12) and abs(rot[0, 1]) > 1e-4
    zoom = np.asarray(fine_motion("zoom", SIZE, rng).matrix)
    assert zoom[0, 1] == 0.0 and zoom[0, 0] == zoom[1, 1] != 1.0
    shift = fine_motion("shift", SIZE, rng)
    assert np.allclose(shift.matrix, np.eye(2)) and math.hypot(*shift.offset) >= 0.3
    with pytest.raises(ConfigError):
        fine_motion("spin", SIZE, rng)
    with pytest.raises(ConfigError):
        LinearMotion((0.0, 0.0), ((1.6, 0.0), (0.0, 1.0)))


def test_band_texture_is_linear_in_its_field_and_flat_areas_are_flat() -> None:
    rng = np.random.default_rng(1)
    tex = BandTexture.band(rng, 1 / 10, 1 / 3, lo=0.2, hi=0.6)
    p = np.random.default_rng(2).uniform(0, 100, (500, 2))
    f = tex.field(p)
    inside = np.abs(f) < tex.clip
    assert np.allclose(tex.grey(p)[inside], 0.4 + 0.2 * f[inside] / tex.clip, atol=1e-12)
    assert 0.8 < np.std(tex.field(np.random.default_rng(3).uniform(0, 1000, (4000, 2)))) < 1.2
    mask = BandTexture.band(rng, 1 / 40, 1 / 20, n=8)
    flat = BandTexture(tex.freqs, tex.phases, tex.amps, tex.tint, 0.2, 0.6, flat=mask, flat_level=0.33)
    deep = mask.field(p) > flat.flat_ramp  # well inside the flat area
    assert deep.any() and np.allclose(flat.grey(p)[deep], 0.33)
