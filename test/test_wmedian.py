"""The weighted median after a warp (wmedian.py, numba_wmedian.py; docs/engine.md "Weighted median"): the numba
kernel gives the reference's values, the weights move a boundary's spill onto the image edge and give occluded
pixels their neighbours' flow, and the fields select it."""

from __future__ import annotations

import numpy as np
import pytest

from flow_node import FlowConfig
from flow_node.core.backends import NUMPY, select_backend
from flow_node.core.errors import ConfigError
from flow_node.core.numba_wmedian import weighted_median_numba
from flow_node.core.refine import warp_median
from flow_node.core.wmedian import median_filter, occlusion_weight, weighted_median, window_range

AGREE = 1e-5  # the numba kernels' agreement with the numpy reference (docs/engine.md, "Compiled kernels")


def two_motions(h: int, w: int, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """A noisy flow with two motions (a disc moving against the background) and a textured frame 0."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:h, :w]
    disc = (yy - h / 2) ** 2 + (xx - w / 3) ** 2 < (min(h, w) / 3) ** 2
    v = np.stack([np.where(disc, 2.5, -0.5), np.where(disc, -1.0, 0.3)]).astype(np.float32)
    v += rng.normal(0.0, 0.3, v.shape).astype(np.float32)
    i0 = (0.3 + 0.4 * disc + 0.05 * rng.random((h, w))).astype(np.float32)
    return v, i0


@pytest.mark.parametrize("shape", [(1, 1), (1, 9), (7, 1), (2, 3), (6, 8), (40, 56), (97, 146)])
@pytest.mark.parametrize("size, sigma_i, sigma_d, tau", [(5, 0.06, 0.15, 0.5), (3, 0.02, 0.0, 0.0),
                                                         (5, 1.0, 2.0, 0.0), (5, 0.001, 0.05, 0.3)])
def test_the_kernel_is_the_reference(shape: tuple[int, int], size: int, sigma_i: float, sigma_d: float,
                                     tau: float) -> None:
    v, i0 = two_motions(*shape)
    ref = weighted_median(v, i0, size, sigma_i, sigma_d, tau)
    got = weighted_median_numba(v, i0, size, sigma_i, sigma_d, tau)
    assert got.dtype == np.float32 and got.shape == v.shape
    np.testing.assert_allclose(got, ref, rtol=0, atol=AGREE)
    if min(shape) >= 40:
        plain = median_filter(v, size)
        assert (window_range(v, size) > tau).mean() > 0.05  # windows of two motions were weighted ...
        assert np.abs(ref - plain).max() > 0.1  # ... and the weights changed flows: not a vacuous agreement


def test_off_is_the_plain_median() -> None:
    v, i0 = two_motions(30, 40)
    for f in (weighted_median, weighted_median_numba):
        np.testing.assert_array_equal(f(v, i0, 5, 0.0, 0.15, 0.5), median_filter(v, 5))
        np.testing.assert_array_equal(f(v, i0, 5, 0.06, 0.15, 1e6), median_filter(v, 5))  # no window of two


@pytest.mark.parametrize("f", [weighted_median, weighted_median_numba])
def test_the_jump_moves_to_the_image_edge(f) -> None:  # noqa: ANN001
    """Frame 0 has an edge between columns 9 and 10; the flow's jump spilled one pixel left of it (column 9 has
    the right side's 3 px). The plain 5 x 5 median keeps the spill (three of the five columns say 3), the weighted
    one takes column 9's flow from the pixels of its own grey value."""
    h, w = 12, 20
    i0 = np.where(np.arange(w) < 10, 0.2, 0.8).astype(np.float32)[None].repeat(h, 0)
    u = np.where(np.arange(w) < 9, 0.0, 3.0).astype(np.float32)[None].repeat(h, 0)
    v = np.stack([u, np.zeros_like(u)])
    assert np.all(median_filter(v, 5)[0, :, 9] == 3.0)
    out = f(v, i0, 5, 0.06, 0.0, 0.5)
    assert np.all(out[0, :, 9] == 0.0) and np.all(out[0, :, 10:] == 3.0) and np.all(out[0, :, :9] == 0.0)


def test_the_occlusion_state() -> None:
    """o is 1 where the flow does not compress and falls where it does (negative divergence)."""
    h, w = 10, 16
    u = np.zeros((h, w), np.float32)
    u[:, 8] = -2.0  # compression at columns 7 and 9 (div = -1), expansion none where u is flat
    v = np.stack([u, np.zeros_like(u)])
    o = occlusion_weight(v, 0.15)
    assert np.all(o[:, :6] == 1.0) and np.all(o[:, 7] < 0.05) and np.all(o[:, 9] == 1.0)  # div(9) = +1
    np.testing.assert_array_equal(occlusion_weight(v, 0.0), 1.0)


def test_the_definition() -> None:
    """The reference against the weighted median written out per pixel: the window's weights (spatial, grey
    value, occlusion state) in integer quanta, the values sorted, the first whose cumulative weight reaches half."""
    from flow_node.core.wmedian import QUANTUM, spatial_weights
    v, i0 = two_motions(9, 11, seed=8)
    size, sigma_i, sigma_d, r = 5, 0.06, 0.15, 2
    got = weighted_median(v, i0, size, sigma_i, sigma_d, 0.0)
    occ = occlusion_weight(v, sigma_d)
    assert occ.min() < 0.5  # some pixels are occluded
    h, w = i0.shape
    for y in range(h):
        for x in range(w):
            ys = [min(max(y + dy, 0), h - 1) for dy in range(-r, r + 1) for dx in range(-r, r + 1)]
            xs = [min(max(x + dx, 0), w - 1) for dy in range(-r, r + 1) for dx in range(-r, r + 1)]
            q = [int(np.floor(s / (1.0 + (float(i0[a, b]) - float(i0[y, x])) ** 2 / sigma_i**2) * occ[a, b] * QUANTUM))
                 + 1 for s, a, b in zip(spatial_weights(size), ys, xs, strict=True)]
            for c in range(2):
                pairs = sorted(zip([v[c, a, b] for a, b in zip(ys, xs, strict=True)], q, strict=True))
                cum = np.cumsum([p[1] for p in pairs])
                assert got[c, y, x] == pairs[int(np.argmax(2 * cum >= cum[-1]))][0]


def test_fields_and_the_warps_it_runs_after() -> None:
    cfg = FlowConfig(median_weight_sigma=0.06)
    assert cfg.median_weight_warps == "every" and cfg.median_occlusion_sigma == 0.15
    for bad in (dict(median_weight_sigma=-1.0), dict(median_weight_warps="first"), dict(median_weight_range=-1.0)):
        with pytest.raises(ConfigError):
            FlowConfig(**bad)
    v, i0 = two_motions(30, 40)
    for backend in (NUMPY, select_backend("numba", threads=1)):
        np.testing.assert_array_equal(warp_median(v, i0, 5, FlowConfig(), backend), median_filter(v, 5))
        np.testing.assert_array_equal(warp_median(v, i0, 5, cfg, backend, weighted=False), median_filter(v, 5))
        np.testing.assert_allclose(warp_median(v, i0, 5, cfg, backend), weighted_median(v, i0, 5, 0.06, 0.15, 0.5),
                                   rtol=0, atol=AGREE)


@pytest.mark.parametrize("window", [3, 5])
def test_the_threads_give_the_same_values(window: int) -> None:
    """Task wmfast: on a level of PARALLEL_MIN_PIXELS or more the kernel weighs interleaved stripes of rows on the
    bound threads; one thread or two, every value is the reference's, bit for bit (blocks split at other pixels,
    the last block's unused columns zeroed)."""
    from flow_node.core.numba_backend import thread_count
    from flow_node.core.numba_wmedian import PARALLEL_MIN_PIXELS
    v, i0 = two_motions(150, 170, seed=5)
    assert v[0].size >= PARALLEL_MIN_PIXELS
    ref = weighted_median(v, i0, 3, 0.06, 0.15, 0.5, window)
    assert not np.array_equal(ref, median_filter(v, 3))
    for n in (1, 2):
        with thread_count(n):
            np.testing.assert_array_equal(weighted_median_numba(v, i0, 3, 0.06, 0.15, 0.5, window), ref)


@pytest.mark.parametrize("n", [1, 2, 9, 25, 49])
def test_the_sorting_network(n: int) -> None:
    """The kernel's network sorts: every 0/1 input for n <= 9 (the 0-1 principle: then it sorts anything), random
    inputs with ties for the larger windows; 140 compare-exchanges for 5 x 5."""
    from flow_node.core.numba_wmedian import sorting_network
    pairs = sorting_network(n)
    assert np.all(pairs[:, 0] < pairs[:, 1]) and (pairs.size == 0 or pairs.max() < n)
    rng = np.random.default_rng(n)
    inputs = ([[(m >> i) & 1 for i in range(n)] for m in range(2**n)] if n <= 9
              else rng.integers(0, 7, (3000, n)).tolist())
    for values in inputs:
        a = list(values)
        for i, j in pairs:
            if a[i] > a[j]:
                a[i], a[j] = a[j], a[i]
        assert a == sorted(values)
    if n == 25:
        assert len(pairs) == 140


def test_which_warps_weigh() -> None:
    from flow_node.core.refine import weighs
    table = {"every": [True] * 4, "last": [False, True, False, True], "finest": [False, False, False, True],
             "coarse": [True, True, False, True]}
    for mode, expected in table.items():
        cfg = FlowConfig(median_weight_sigma=0.06, median_weight_warps=mode)
        got = [weighs(cfg, last, finest) for finest in (False, True) for last in (False, True)]
        assert got == expected, mode


def test_the_presets_that_weigh() -> None:
    """quality weighs after each level's last warp where a window spans 0.75 px (task occl2), fastest (and
    stream_fast, which solves a single pair as fastest does) after every warp of its coarser levels and the finest
    solved level's last (task wmfast: every warp cost it 1.07-1.10x on Middlebury), balanced after each level's last
    where a window spans 1.5 px (occl2: 0.75 px cost it 1.11x on Middlebury); realtime keeps the plain median
    (wmfast: 1.5 px lost the report split's missing regime). At 1.5 px a ~0.6 px jump keeps the plain median, a 3 px
    one not."""
    from flow_node.core.presets import WEIGHTED_MEDIAN
    fastest, quality, balanced = (FlowConfig.preset(name) for name in ("fastest", "quality", "balanced"))
    stream_fast = FlowConfig.preset("stream_fast")
    for key, value in WEIGHTED_MEDIAN.items():
        expected = "coarse" if key == "median_weight_warps" else value
        assert getattr(fastest, key) == getattr(stream_fast, key) == expected
        assert getattr(quality, key) == value
        assert getattr(balanced, key) == (1.5 if key == "median_weight_range" else value)
    assert FlowConfig.preset("realtime").median_weight_sigma == 0.0
    v, i0 = two_motions(30, 40)
    small = (v - v.mean(axis=(1, 2), keepdims=True)) * np.float32(0.2)  # the disc's jump ~0.6 px, the noise 0.06
    for backend in (NUMPY, select_backend("numba", threads=1)):
        np.testing.assert_array_equal(warp_median(small, i0, 5, balanced, backend), median_filter(small, 5))
        assert np.abs(warp_median(v, i0, 5, balanced, backend) - median_filter(v, 5)).max() > 0.1
