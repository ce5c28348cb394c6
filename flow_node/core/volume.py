"""The engine on volumes: flow between two (Z, Y, X) arrays with the paper's models in three dimensions
(docs/engine.md, "Volumes").

The models, operators and the numpy solver are the 2-D ones (models.py, operators.py and solver.py take the
number of spatial axes from the flow); this module adds what is specific to a volume: validation, the pyramid
(area averaging per axis), the trilinear warp and linearisation (numpy reference here, numba kernels in
numba_volume.py) and the coarse-to-fine driver. Flow is (3, Z, Y, X) channel-first inside, in voxels of its
level, components x, y, z; the result is (Z, Y, X, 3) with I1(p + flow(p)) ~ I0(p), as for images.

Of FlowConfig, a volume uses: model, alpha, alpha1, tv_norm, gradient_scheme, iterations, tolerance,
levels, scale_factor, min_size, warps, finest_warps, finest_iterations, level_alpha_factor, backend,
threads and incompressibility. The rest is image-only (photometric modes, initialisations, warp kernel,
median filter, Bregman iterations, finest_level) and is not applied to volumes.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass

import numpy as np

from .backends import numba_available
from .config import FlowConfig
from .errors import ConfigError, InputError, NonFiniteResult
from .models import MODEL_SPECS
from .operators import image_gradient
from .pyramid import pyramid_shapes
from .refine import level_schedule
from .solver import PDState, Problem, SolveParams, solve_numpy

FLOAT_INPUT_LIMIT = 1e6  # as api.FLOAT_INPUT_LIMIT: larger float values are garbage, not intensities
MIN_SIDE = 2  # voxels per axis
# What a volume is solved with when no config is given (API and flow_estimate without --preset): the settings
# the retired bench.volume measured (docs/engine.md, "Volumes"); a stronger alpha than 2-D's and fewer
# iterations, and a pyramid also on volumes of a few dozen slices (min_size 12 left a 20-slice volume a single
# level).
VOLUME_CONFIG = FlowConfig(model="l1_tv", alpha=0.06, warps=5, iterations=20, finest_warps=3, finest_iterations=15,
                           min_size=6, gradient_scheme="interpolated", median_filter=0)


def is_volume(a: object) -> bool:
    """True for a 3-D array at least 5 wide in x: what :func:`~flow_node.core.api.estimate_flow` treats as a
    volume rather than an (H, W, 1..4) image (a thinner volume must use :func:`estimate_volume` directly)."""
    return isinstance(a, np.ndarray) and a.ndim == 3 and a.shape[2] > 4


def to_volume(vol: np.ndarray, name: str = "volume") -> np.ndarray:
    """Validate a volume and convert it to float32 (Z, Y, X): uint8 / 255, uint16 / 65535, float as is (finite,
    magnitude at most FLOAT_INPUT_LIMIT). InputError naming the problem."""
    if not isinstance(vol, np.ndarray):
        raise InputError(f"{name}: expected a numpy array, got {type(vol).__name__}")
    if vol.ndim != 3:
        raise InputError(f"{name}: expected a volume of shape (Z, Y, X), got {vol.ndim} dimension(s) {vol.shape}")
    if min(vol.shape) < MIN_SIDE:
        raise InputError(f"{name}: volume is {vol.shape}; need at least {MIN_SIDE} voxels per axis")
    if vol.dtype in (np.uint8, np.uint16):
        return np.divide(vol, np.float32(255.0 if vol.dtype == np.uint8 else 65535.0), dtype=np.float32)
    if vol.dtype not in (np.float16, np.float32, np.float64):
        raise InputError(f"{name}: unsupported dtype {vol.dtype}; use uint8, uint16 or float")
    out = np.ascontiguousarray(vol, dtype=np.float32)
    peak = float(np.max(np.abs(out)))
    if not math.isfinite(peak):
        raise InputError(f"{name}: contains NaN or infinite values")
    if peak > FLOAT_INPUT_LIMIT:
        raise InputError(f"{name}: float values reach {peak:.3g} (magnitude at most {FLOAT_INPUT_LIMIT:g})")
    return out


def normalise_pair(v0: np.ndarray, v1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Both volumes mapped by one affine map so that the pair spans [0, 1] (a constant pair is left as is): a
    weight then means the same for any bit depth or contrast."""
    lo = min(float(v0.min()), float(v1.min()))
    span = max(float(v0.max()), float(v1.max())) - lo
    if span <= 0.0:
        return v0, v1
    scale = np.float32(1.0 / span)
    return (v0 - np.float32(lo)) * scale, (v1 - np.float32(lo)) * scale


# ------------------------------------------------------------------------------------ resampling per axis
def area_matrix(n_in: int, n_out: int) -> np.ndarray:
    """(n_out, n_in) weights of area averaging: output cell o covers [o, o + 1) * n_in / n_out of the input;
    each row holds the overlaps with the input cells, divided by the cell's length (rows sum to 1)."""
    edges = np.arange(n_out + 1) * (n_in / n_out)
    lo, hi = edges[:-1, None], edges[1:, None]
    cells = np.arange(n_in)[None, :]
    overlap = np.clip(np.minimum(hi, cells + 1) - np.maximum(lo, cells), 0.0, None)
    return (overlap / (n_in / n_out)).astype(np.float32)


def linear_matrix(n_in: int, n_out: int) -> np.ndarray:
    """(n_out, n_in) weights of linear interpolation with aligned cell centres, x_in = (x_out + 1/2) n_in /
    n_out - 1/2, clamped to the first and last sample."""
    x = np.clip((np.arange(n_out) + 0.5) * (n_in / n_out) - 0.5, 0.0, n_in - 1)
    x0 = np.minimum(np.floor(x).astype(int), n_in - 1)
    x1 = np.minimum(x0 + 1, n_in - 1)
    m = np.zeros((n_out, n_in), np.float32)
    np.add.at(m, (np.arange(n_out), x0), 1.0 - (x - x0))
    np.add.at(m, (np.arange(n_out), x1), x - x0)
    return m


def resample(f: np.ndarray, shape: tuple[int, int, int], matrix: Callable[[int, int], np.ndarray]) -> np.ndarray:
    """f (..., Z, Y, X) resampled to (..., *shape) by ``matrix`` (area_matrix or linear_matrix) along each of
    the last three axes, as matrix products on views (no transposed copies). float32 C-contiguous."""
    out = f.astype(np.float32, copy=False)
    lead = f.shape[:-3]
    nz, ny, nx = f.shape[-3:]
    if nx != shape[2]:
        out = (out.reshape(-1, nx) @ matrix(nx, shape[2]).T).reshape(out.shape[:-1] + (shape[2],))
    if ny != shape[1]:
        out = matrix(ny, shape[1]) @ out
    if nz != shape[0]:
        plane = out.shape[-2:]
        out = (matrix(nz, shape[0]) @ out.reshape(lead + (nz, -1))).reshape(lead + (shape[0],) + plane)
    return np.ascontiguousarray(out)


def resize_flow3(v: np.ndarray, shape: tuple[int, int, int], how: Callable[..., np.ndarray] = resample
                 ) -> np.ndarray:
    """Flow (3, z, y, x) in voxels of its grid -> (3, *shape): linear resampling (by ``how``: :func:`resample`
    or a backend's), each component scaled by its own axis's ratio (component 0 = x = the last axis)."""
    out = how(v, shape, linear_matrix)
    for comp in range(3):
        out[comp] *= np.float32(shape[2 - comp] / v.shape[3 - comp])
    return out


def resize_state3(state: PDState, shape: tuple[int, int, int], how: Callable[..., np.ndarray] = resample
                  ) -> PDState:
    """A level's solver state on the next finer grid: the flow by :func:`resize_flow3`, the duals (and w)
    linearly resampled with their values kept, so the finer level starts from the coarser one's solution."""
    def field(f: np.ndarray | None) -> np.ndarray | None:
        return None if f is None else how(f, shape, linear_matrix)

    return PDState(resize_flow3(state.v, shape, how), field(state.y), field(state.w), field(state.z),
                   field(state.s))


# ----------------------------------------------------------------------------- linearisation (numpy reference)
def warp_source3(i1: np.ndarray, scheme: str) -> np.ndarray:
    """What each warp of a level samples: (4, Z, Y, X) float32 = [I1, its image gradient (x, y, z)]."""
    src = np.empty((4,) + i1.shape, np.float32)
    src[0] = i1
    image_gradient(src[0], scheme, out=src[1:])
    return src


def linearise3(i0: np.ndarray, src: np.ndarray, v0: np.ndarray, gi0: np.ndarray | None
               ) -> tuple[np.ndarray, np.ndarray]:
    """Linearised brightness constancy around v0 on a volume (operators.linearise in 3-D, trilinear):
    a = grad I1(p + v0) (averaged with gi0, the gradient of I0, when given: the ``interpolated`` scheme),
    c = I1(p + v0) - I0(p) - a . v0; both zero where p + v0 leaves the volume. a (3, Z, Y, X), c (Z, Y, X)."""
    nz, ny, nx = i0.shape
    grid = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    pos = [grid[2 - comp] + v0[comp] for comp in range(3)]  # x, y, z sampling positions
    inside = np.ones(i0.shape, bool)
    for p, n in zip(pos, (nx, ny, nz), strict=True):
        inside &= (p >= 0.0) & (p <= n - 1)
    lo = [np.clip(np.floor(p), 0, n - 1).astype(np.intp) for p, n in zip(pos, (nx, ny, nz), strict=True)]
    hi = [np.minimum(i + 1, n - 1) for i, n in zip(lo, (nx, ny, nz), strict=True)]
    fr = [(p - i).astype(np.float32) for p, i in zip(pos, lo, strict=True)]
    out = np.zeros((4,) + i0.shape, np.float32)
    for corner in range(8):
        ix, iy, iz = (hi[k] if corner >> k & 1 else lo[k] for k in range(3))
        wt = np.ones(i0.shape, np.float32)
        for k in range(3):
            wt *= fr[k] if corner >> k & 1 else 1.0 - fr[k]
        out += wt * src[:, iz, iy, ix]
    a = out[1:] if gi0 is None else 0.5 * (gi0 + out[1:])
    c = out[0] - i0 - a[0] * v0[0] - a[1] * v0[1] - a[2] * v0[2]
    return (a * inside).astype(np.float32), (c * inside).astype(np.float32)


# ----------------------------------------------------------------------------------------- backends
@dataclass(frozen=True)
class VolumeBackend:
    """The per-warp work on a volume: ``linearise(i0, src, v0, gi0) -> (a, c)`` and the level solver
    ``solve(problem, state, params) -> iterations`` (solver.LevelSolver), numpy reference or numba."""

    name: str
    linearise: Callable[..., tuple[np.ndarray, np.ndarray]]
    solve: Callable[[Problem, PDState, SolveParams], int]
    resample: Callable[..., np.ndarray]
    on_threads: Callable[[int], AbstractContextManager[object]] = lambda n: nullcontext()


NUMPY_VOLUME = VolumeBackend("numpy", linearise3, solve_numpy, resample)


def select_volume_backend(name: str) -> VolumeBackend:
    """numba for ``numba`` (ConfigError when it cannot be imported) and ``auto`` (numpy when it cannot)."""
    if name == "numpy" or (name == "auto" and not numba_available()):
        return NUMPY_VOLUME
    if not numba_available():
        raise ConfigError("backend 'numba' requested but numba cannot be imported")
    from . import numba_backend, numba_volume, numba_volume_resample  # optional dependency: imported only when selected

    return VolumeBackend("numba", numba_volume.linearise_numba, numba_volume.solve_numba,
                         numba_volume_resample.resample_numba, numba_backend.thread_count)


# ------------------------------------------------------------------------------------------- driver
@dataclass
class VolumeResult:
    """Flow (Z, Y, X, 3) float32, components x, y, z in voxels per frame, and what the solve did."""

    flow: np.ndarray
    seconds: float
    backend: str
    shapes: list[tuple[int, ...]]
    iterations: int


def check_pair(v0: np.ndarray, v1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Both volumes validated (:func:`to_volume`) and of one shape, else InputError."""
    for name, vol in (("frame0", v0), ("frame1", v1)):
        if isinstance(vol, np.ndarray) and vol.ndim != 3:
            raise InputError(f"frame0 and frame1 must both be volumes (Z, Y, X); {name} has shape {vol.shape}")
    i0, i1 = to_volume(v0, "frame0"), to_volume(v1, "frame1")
    if i0.shape != i1.shape:
        raise InputError(f"volumes differ in shape: frame0 is {i0.shape}, frame1 is {i1.shape} (Z, Y, X)")
    return i0, i1


def solve_level3(i0: np.ndarray, i1: np.ndarray, state: PDState, cfg: FlowConfig, level: int,
                 backend: VolumeBackend) -> int:
    """The warps of one level (:func:`~flow_node.core.refine.level_schedule`): linearise around the current
    flow, run the solver from the current state. Returns the iterations run."""
    warps, iterations = level_schedule(cfg, level == 0)
    params = SolveParams(MODEL_SPECS[cfg.model], cfg.alpha * cfg.level_alpha_factor**level, cfg.alpha1,
                         cfg.tv_norm, iterations, cfg.tolerance, cfg.incompressibility)
    src = warp_source3(i1, cfg.gradient_scheme)
    gi0 = image_gradient(i0, cfg.gradient_scheme) if cfg.gradient_scheme == "interpolated" else None
    total = 0
    for _ in range(warps):
        a, c = backend.linearise(i0, src, state.v, gi0)
        total += backend.solve(Problem(a, c), state, params)
    return total


def estimate_volume(v0: np.ndarray, v1: np.ndarray, config: FlowConfig | None = None) -> VolumeResult:
    """Flow from volume v0 to v1 (same (Z, Y, X) shape; uint8, uint16 or float): coarse to fine from zero
    flow, each level starting from the coarser one's state (:func:`resize_state3`). ``config`` defaults to
    :data:`VOLUME_CONFIG`."""
    cfg = config if config is not None else VOLUME_CONFIG
    i0, i1 = normalise_pair(*check_pair(v0, v1))
    backend = select_volume_backend(cfg.backend)
    start = time.perf_counter()
    shapes = pyramid_shapes(i0.shape, cfg.levels, cfg.scale_factor, cfg.min_size)
    spec, incompressible = MODEL_SPECS[cfg.model], cfg.incompressibility > 0.0
    state, total = PDState.zeros(spec, shapes[-1], incompressible), 0
    with backend.on_threads(cfg.threads):
        for level in range(len(shapes) - 1, -1, -1):
            shape = shapes[level]
            if state.v.shape[1:] != shape:
                state = resize_state3(state, shape, backend.resample)
            l0 = i0 if level == 0 else backend.resample(i0, shape, area_matrix)
            l1 = i1 if level == 0 else backend.resample(i1, shape, area_matrix)
            total += solve_level3(l0, l1, state, cfg, level, backend)
    flow = np.ascontiguousarray(np.moveaxis(state.v, 0, -1), dtype=np.float32)
    if not np.isfinite(flow).all():
        raise NonFiniteResult("the engine's volume flow has NaN/inf values: input unusable")
    return VolumeResult(flow, time.perf_counter() - start, backend.name, shapes, total)
