"""The warp: sub-pixel phase error on ramps and band-limited signals, numba against the numpy reference,
and flow on exactly rendered pairs (where OpenCV's INTER_CUBIC, Keys a = -0.75, is visibly biased)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from synth import constant_flow, interior, pair_from_flow, rotation_flow, texture

from flow_node import FlowConfig, aee
from flow_node.core import numba_backend
from flow_node.core.backends import Backend, select_backend
from flow_node.core.config import GRADIENT_SCHEMES
from flow_node.core.numba_backend import WARPER, bspline_prefilter_numba, linearise_numba, warp_numba
from flow_node.core.operators import image_gradient, linearise, warp_source
from flow_node.core.refine import coarse_to_fine
from flow_node.core.warping import KERNELS, Warper, bspline_prefilter, warp

PHASES = np.arange(1, 8) / 8.0
WARPS = {"numpy": warp, "numba": warp_numba}


def opencv_cubic(img: np.ndarray, map_x: np.ndarray, map_y: np.ndarray, kernel: str = "") -> np.ndarray:
    """The engine's former warp (OpenCV INTER_CUBIC), the negative control of these tests."""
    planes = img.reshape((-1,) + img.shape[-2:])
    out = [cv2.remap(np.ascontiguousarray(p), map_x, map_y, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE)
           for p in planes]
    return np.stack(out).reshape(img.shape[:-2] + map_x.shape)


def phase_errors(signal, sampler, kernel: str) -> np.ndarray:  # noqa: ANN001
    """Mean error of sampling signal(x) (a 1-D function, drawn on a 16 x 64 grid) at x = 20..43 + phase."""
    xs = np.arange(64, dtype=np.float64)
    img = np.tile(signal(xs), (16, 1)).astype(np.float32)
    errs = []
    for phase in PHASES:
        at = np.tile(np.arange(20, 44) + phase, (4, 1)).astype(np.float32)
        got = sampler(img, at, np.full_like(at, 8.0), kernel)
        errs.append(float(np.abs(got - signal(at.astype(np.float64))).max()))
    return np.array(errs)


@pytest.mark.parametrize("backend", sorted(WARPS))
@pytest.mark.parametrize("kernel", KERNELS)
def test_a_ramp_is_reproduced_at_every_sub_pixel_phase(kernel: str, backend: str) -> None:
    assert phase_errors(lambda x: 0.01 * x, WARPS[backend], kernel).max() < 2e-5  # 1e-5 of a 0..0.64 ramp


def test_opencv_cubic_is_biased_on_a_ramp() -> None:
    """The bias the engine's warp no longer has: up to 0.047 px on a ramp of slope 1 (here slope 0.01)."""
    errs = phase_errors(lambda x: 0.01 * x, opencv_cubic, "")
    assert errs.max() > 3e-4 and errs[3] < 1e-5  # biased everywhere but at phase 1/2


def test_band_limited_signal_phase_error_is_small_and_bspline_is_smallest() -> None:
    signal = lambda x: 0.5 + 0.4 * np.sin(2 * np.pi * 0.15 * x + 0.3)  # noqa: E731 -- 6.7 px period
    err = {k: phase_errors(signal, warp, k).max() for k in KERNELS}
    err["opencv"] = phase_errors(signal, opencv_cubic, "").max()
    assert err["bspline"] < 5e-3
    assert err["bspline"] < 0.5 * err["keys"] < 0.5 * err["opencv"]


@pytest.mark.parametrize("kernel", KERNELS)
def test_numba_warp_matches_the_numpy_reference(kernel: str) -> None:
    rng = np.random.default_rng(3)
    img = rng.random((3, 37, 53)).astype(np.float32)
    map_x = rng.uniform(-4, 57, (29, 41)).astype(np.float32)  # outside positions read the clamped border
    map_y = rng.uniform(-4, 41, (29, 41)).astype(np.float32)
    map_x[0, :4] = (-1.0, -1e-7, 2.0, 52.0)  # integer and just-below-integer positions
    assert np.abs(warp_numba(img, map_x, map_y, kernel) - warp(img, map_x, map_y, kernel)).max() < 1e-5
    assert np.abs(warp_numba(img[0], map_x, map_y, kernel) - warp(img[0], map_x, map_y, kernel)).max() < 1e-5
    assert np.abs(bspline_prefilter_numba(img) - bspline_prefilter(img)).max() < 1e-5


@pytest.mark.parametrize("scheme", GRADIENT_SCHEMES)
@pytest.mark.parametrize("kernel", KERNELS)
@pytest.mark.parametrize("parallel", [False, True])
def test_numba_linearise_matches_the_numpy_reference(kernel: str, scheme: str, parallel: bool,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """The fused linearisation kernel: a and c as operators.linearise, including the pixels whose target
    leaves the image (zero there), odd sizes and the parallel rows."""
    for name in ("PARALLEL_MIN_PIXELS", "LINEARISE_PARALLEL_MIN_PIXELS"):  # the warp source's sample, the kernel
        monkeypatch.setattr(numba_backend, name, 0 if parallel else 10**9)
    rng = np.random.default_rng(5)
    i0, i1 = rng.random((2, 31, 45)).astype(np.float32)
    flow = (2.5 * rng.standard_normal((2, 31, 45))).astype(np.float32)
    flow[:, 3, :5] = ((-0.5, 0.0, 1e-7, 44.0, -3.0), (0.0, -1e-7, 30.0, 0.0, 31.0))  # on / just off the border
    src = warp_source(i1, scheme, kernel, WARPER)
    g0 = image_gradient(i0, scheme) if scheme == "interpolated" else None
    a_ref, c_ref = linearise(i0, src, g0, flow, scheme, kernel)
    a, c = linearise_numba(i0, src, g0, flow, scheme, kernel)
    outside = c_ref == 0
    assert 0.05 < outside.mean() < 0.5 and np.all(c[outside] == 0) and np.all(a[:, outside] == 0)
    assert np.abs(a - a_ref).max() < 1e-5 and np.abs(c - c_ref).max() < 1e-5


@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (7, 1), (2, 2), (3, 3), (2, 5), (5, 3), (4, 4), (6, 9)])
@pytest.mark.parametrize("parallel", [False, True])
def test_numba_linearise_matches_the_numpy_reference_on_tiny_images(shape: tuple[int, int], parallel: bool,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """Tiny and odd sizes, where every target's 4 x 4 taps cross a border (mirrored) or only a few pixels have
    unmirrored interior blocks: every target inside the image, a third of them exactly on or half a pixel
    from the first or last row or column. Both kernels, every gradient scheme, serial and parallel rows."""
    monkeypatch.setattr(numba_backend, "LINEARISE_PARALLEL_MIN_PIXELS", 0 if parallel else 10**9)
    rng = np.random.default_rng(sum(shape))
    h, w = shape
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float32)
    tx, ty = rng.uniform(0, w - 1, (h, w)), rng.uniform(0, h - 1, (h, w))
    tx.flat[::3] = rng.choice([0.0, 0.5, w - 1.5, w - 1.0], tx.size)[::3].clip(0, w - 1)
    ty.flat[1::3] = rng.choice([0.0, 0.5, h - 1.5, h - 1.0], ty.size)[1::3].clip(0, h - 1)
    flow = np.stack([tx - xs, ty - ys]).astype(np.float32)
    i0, i1 = rng.random((2, h, w)).astype(np.float32)
    for kernel in KERNELS:
        for scheme in GRADIENT_SCHEMES:
            src = warp_source(i1, scheme, kernel, WARPER)
            g0 = image_gradient(i0, scheme) if scheme == "interpolated" else None
            a_ref, c_ref = linearise(i0, src, g0, flow, scheme, kernel)
            a, c = linearise_numba(i0, src, g0, flow, scheme, kernel)
            assert np.abs(a - a_ref).max() < 1e-5 and np.abs(c - c_ref).max() < 1e-5, (kernel, scheme)


def test_bspline_interpolates_its_samples() -> None:
    img = np.random.default_rng(4).random((20, 30)).astype(np.float32)
    ys, xs = np.mgrid[0:20, 0:30].astype(np.float32)
    assert np.abs(warp(img, xs, ys, "bspline") - img).max() < 1e-5


@pytest.mark.parametrize("motion", ["translation", "rotation"])
def test_exact_pairs_show_the_warp_bias(motion: str) -> None:
    """On exactly rendered pairs the engine's warp reaches AEE 0.002-0.01; the old OpenCV warp 0.04-0.05."""
    h, w = 64, 80
    gt = constant_flow(h, w, 0.6, -0.35) if motion == "translation" else rotation_flow(h, w, 2.0)
    i0, i1 = pair_from_flow(texture(h, w, 1), gt)
    # the grey-value data term: its residual is what the warp's interpolation error enters directly
    cfg = FlowConfig(model="l1_tv", levels=3, warps=3, iterations=50, median_filter=0, photometric="normalise")
    backend = select_backend("numba")
    err = {}
    opencv = Warper(opencv_cubic, lambda img: img)  # keys: no prefilter
    for kernel, warper in (("bspline", backend.warper), ("keys", backend.warper), ("opencv", opencv)):
        flow, _ = coarse_to_fine(i0, i1, cfg.replace(warp_kernel=kernel if kernel != "opencv" else "keys"),
                                 Backend(kernel, backend.solve, warper))
        err[kernel] = aee(interior(flow), interior(gt))
    assert err["bspline"] < 0.005 and err["keys"] < 0.012
    assert err["opencv"] > 0.03
