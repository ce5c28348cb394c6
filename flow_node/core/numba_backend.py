"""The numba backend: :func:`solve_numba`, a drop-in :data:`~flow_node.core.solver.LevelSolver`, and
:data:`WARPER`, the compiled :class:`flow_node.core.warping.Warper`.

Same semantics as solver.solve_numpy (scaling E / alpha, update order, stopping rule every CHECK_EVERY
iterations, Bregman linear term ``problem.b``); the kernels are in numba_kernels.py (iteration) and
numba_warp.py (warp, prefilter, linearisation: :func:`linearise_numba`). Differences that do
not change results beyond float32 rounding: the state arrays are updated in place (made float32
C-contiguous first if they are not) and the extrapolated variables v_bar / w_bar live in the calling
thread's scratch arrays (workspace.py), reused across calls of the same image size.

Compiled kernels are cached on disk (``cache=True``): in NUMBA_CACHE_DIR when set (the Makefile sets
``.venv/numba_cache``), otherwise numba writes ``__pycache__`` next to this file, or, when the package
directory is not writable (an installed package), a per-user directory under ~/.cache. One compiled
specialisation serves every model and TV norm, so any warm-up solve compiles all of it.

Importing this module raises ImportError when numba is not installed; backends.py then falls back to numpy.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import AbstractContextManager, contextmanager
from functools import lru_cache

import cv2
import numba
import numpy as np

from . import numba_kernels as nk
from . import numba_warp as nw
from .models import mass_steps
from .operators import image_gradient
from .solver import CHECK_EVERY, MASS_DATA_SCALE, PDState, Problem, SolveParams, shift_slow_modes
from .warping import BSPLINE_POLE, HORIZON, KERNEL_CODES, Warper
from .workspace import scratch, scratch_parts

_F32 = np.float32
# The defaults of the parallel thresholds (a FlowConfig's parallel_min_pixels > 0 replaces both for its estimator:
# backends.select_backend binds it to solve_numba and linearise_numba):
PARALLEL_MIN_PIXELS = 120_000  # below this a level runs the serial kernels (thread start-up dominates)
# the linearisation costs ~10 primal-dual iterations per pixel in one pass: worth the threads on smaller levels
LINEARISE_PARALLEL_MIN_PIXELS = 20_000
_DUMMY3 = np.zeros((2, 1, 1), _F32)
_DUMMY4 = np.zeros((2, 2, 1, 1), _F32)
_DUMMY5 = np.zeros((2, 2, 2, 1, 1), _F32)
_DUMMY2 = np.zeros((1, 1), _F32)


def resolve_threads(n: int) -> int:
    """The thread count a ``threads`` setting means: all cores for 0 (or less), values above the core count
    clipped to it."""
    return numba.config.NUMBA_NUM_THREADS if n <= 0 else min(int(n), numba.config.NUMBA_NUM_THREADS)


@contextmanager
def thread_count(n: int) -> Iterator[int]:
    """Run the kernels called in this block on :func:`resolve_threads` (n) threads; yields that count.

    numba's thread count belongs to the calling thread, so this binds it for this block in this thread only
    (an estimator's solve in another thread keeps its own); the count before is restored on exit."""
    before = numba.get_num_threads()
    numba.set_num_threads(resolve_threads(n))
    try:
        yield numba.get_num_threads()
    finally:
        numba.set_num_threads(before)


def threads_for(work: int, min_work: int) -> AbstractContextManager[int]:
    """:func:`thread_count` for a call of ``work`` units (pixels, or pixels x taps): the calling thread's
    :func:`threads` from ``min_work`` on, one thread below it (a parallel region's start and join would
    cost more than the work)."""
    return thread_count(threads() if work >= min_work else 1)


def threads() -> int:
    """Threads the parallel kernels run on when called now from this thread (inside an estimator's call:
    its ``threads`` setting, bound by :func:`thread_count`; elsewhere numba's count for the thread)."""
    return numba.get_num_threads()


def cache_dir() -> str:
    """Where compiled kernels are cached: NUMBA_CACHE_DIR if set, else numba's default (``__pycache__``
    beside numba_kernels.py, or a per-user fallback when the package directory is read-only)."""
    return numba.config.CACHE_DIR or "numba default (__pycache__ beside the package, else per-user)"


def parallel_at(pixels: int, min_pixels: int) -> bool:
    """Whether a level of ``pixels`` runs the parallel kernels: more than one thread bound and at least
    ``min_pixels`` pixels."""
    return pixels >= min_pixels and threads() > 1  # the size first: threads() costs ~2 us a call


def _f32c(x: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=_F32)


def work_buffers(v: np.ndarray, w: np.ndarray | None, rows: dict[str, np.ndarray] | None = None
                 ) -> tuple[np.ndarray, ...]:
    """(v_bar, w_bar, xbuf, zero_b) for this shape: the extrapolated variables (2, H, W) and (2, 2, H, W)
    (without w: the zero row of :func:`zero_rows`), the per-thread row scratch of the primal kernel
    (threads, 2, W + 1) and the zero Bregman row (2, 1, W), float32. The calling thread's scratch arrays
    (workspace.py), reused across calls and frames. ``rows``: :func:`zero_rows` (width) if the caller has them."""
    width = v.shape[2]
    rows = zero_rows(width) if rows is None else rows
    return (scratch("numba.v_bar", v.shape), scratch("numba.w_bar", w.shape) if w is not None else rows["w_bar"],
            scratch("numba.xbuf", (numba.config.NUMBA_NUM_THREADS, 2, width + 1)), rows["b"])


# shapes of the zero rows that stand for an absent array a pixel loop of the kernels indexes (W = width)
ZERO_ROWS = {"b": lambda w: (2, 1, w), "w_bar": lambda w: (2, 2, 1, w), "p": lambda w: (1, w),
             "tv": lambda w: (2, 1, w), "qpad": lambda w: (2, 2, 1, w + 2), "g0": lambda w: (2, 1, w)}
# the same for the volume kernels (numba_volume.py; X = width): w_bar without w, z of tv_l2, gi0 without the
# interpolated scheme -- one row of one slice, read at a clamped (slice, row) index
VOLUME_ZERO_ROWS = {"w_bar": lambda x: (3, 3, 1, 1, x), "z": lambda x: (3, 3, 3, 1, 1, x),
                    "gi0": lambda x: (3, 1, 1, x)}


def zero_rows(width: int, volume: bool = False) -> dict[str, np.ndarray]:
    """Zero rows for images ``width`` wide, float32, written (so their pages are present): the Bregman term
    without one (``b``), and what the iteration kernels get instead of w_bar, p, tv and qpad when the model
    has none, and the linearisation instead of frame 0's gradient when the scheme needs none (shapes
    :data:`ZERO_ROWS`; ``volume``: the volume kernels', :data:`VOLUME_ZERO_ROWS`). The kernels clamp their
    row index into these (numba_kernels.py: a flag's branch in a pixel loop becomes masked loads, and a
    masked lane on an untouched page costs a microcode assist per vector step). Views of one of the calling
    thread's scratch arrays, zeroed on every call (~11 W floats; volumes 39 X); the views are made once per
    array (workspace.scratch_parts: cutting the array into them cost ~4 of the ~5 us a call took, six calls a
    stream frame)."""
    flat, rows = scratch_parts("numba.volume_rows" if volume else "numba.zero_rows", _row_shapes(width, volume))
    flat.fill(0.0)
    return rows


def unit_row(width: int) -> np.ndarray:
    """A (1, ``width``) row of ones, float32: what the dual pass reads as the radius of y's ball without an edge
    weight (the unit ball; numba_kernels.prox_dual4). The calling thread's scratch array, written on every call."""
    row = scratch("numba.unit_row", (1, width))
    row.fill(1.0)
    return row


@lru_cache(maxsize=64)
def _row_shapes(width: int, volume: bool) -> tuple[tuple[str, tuple[int, ...]], ...]:
    """The (name, shape) of each of :func:`zero_rows`' rows for ``width`` (:data:`ZERO_ROWS` or
    :data:`VOLUME_ZERO_ROWS`)."""
    return tuple((name, shape(width)) for name, shape in (VOLUME_ZERO_ROWS if volume else ZERO_ROWS).items())


def row_scratch(width: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-thread row scratch of the linearisation kernel for images ``width`` wide: tap weights and mask
    (threads, 9, width) float32, tap bases (threads, 2, width) int32; the calling thread's scratch arrays."""
    return scratch("numba.linearise_rows", (numba.config.NUMBA_NUM_THREADS, 9, width)), row_base(width)


def row_base(width: int) -> np.ndarray:
    """The tap bases of :func:`row_scratch` alone, (threads, 2, width) int32 (the census kernel keeps its tap
    weights in its own rings)."""
    return scratch("numba.linearise_base", (numba.config.NUMBA_NUM_THREADS, 2, width), np.int32)


def solve_numba(problem: Problem, state: PDState, p: SolveParams, min_pixels: int | None = None) -> int:
    """Run up to p.iterations primal-dual steps on ``problem`` from ``state`` (updated in place).

    Stops early, checked every CHECK_EVERY iterations, when the RMS change of v per iteration falls below
    p.tolerance (px); returns the number of iterations run. Semantics of solver.solve_numpy. A level of
    ``min_pixels`` pixels or more (None: PARALLEL_MIN_PIXELS) runs the parallel kernels when more than one
    thread is bound (same numbers as the serial ones: each pixel's update is the same arithmetic).
    """
    spec = p.spec
    state.v, state.y = _f32c(state.v), _f32c(state.y)
    if state.w is not None:
        state.w = _f32c(state.w)
    if state.z is not None:
        state.z = _f32c(state.z)
    rows = zero_rows(state.v.shape[2])
    v_bar, w_bar, xbuf, zero_b = work_buffers(state.v, state.w, rows)
    mass = problem.m is not None
    bc = mass and problem.ab is not None
    if mass:
        state.p = _f32c(state.data_dual())
        sp, tv = mass_steps(problem.a, problem.m, spec.tau, MASS_DATA_SCALE)
        h, w = state.v.shape[1:]
        qpad = scratch("numba.mass_q", (2, 2, h + 2, w + 2))
        qpad.fill(0.0)  # the ring stays zero; the kernel writes the inside from p before reading it
    np.copyto(v_bar, state.v)
    if state.w is not None:
        np.copyto(w_bar, state.w)
    kernel = getattr(nk, nk.ITERATE_NAMES[nk.data_code(problem.q is not None, mass, bc)])  # looked up per call
    k = int(kernel(
        state.v, state.y,
        state.w if state.w is not None else _DUMMY4,
        state.z if state.z is not None else _DUMMY5,
        v_bar, w_bar, _f32c(problem.a if problem.q is None else problem.q), _f32c(problem.c),
        _f32c(problem.b) if problem.b is not None else zero_b, xbuf,
        _F32(spec.tau), _F32(spec.sigma), _F32(spec.tau / p.alpha), _F32(p.alpha1 / p.alpha),
        spec.data == "l1", _F32(2.0 * p.gamma * p.alpha / spec.tau),  # soft = 2 gamma / tau_d (nk.prox_data)
        nk.REG_CODES[spec.regulariser], p.tv_norm == "isotropic", problem.b is not None,
        int(p.iterations), float(p.tolerance), CHECK_EVERY,
        parallel_at(state.v.shape[1] * state.v.shape[2], PARALLEL_MIN_PIXELS if min_pixels is None else min_pixels),
        problem.q is not None,
        mass, _f32c(problem.m) if mass else _DUMMY4, state.p if mass else rows["p"], qpad if mass else rows["qpad"],
        sp if mass else _DUMMY2,
        tv if mass else rows["tv"], _F32(1.0 / p.alpha),
        _f32c(problem.ab) if bc else _DUMMY3, _f32c(problem.cb) if bc else _DUMMY2,
        unit_row(state.v.shape[2]) if problem.g is None else _f32c(problem.g), _F32(p.relaxation - 1.0)))
    if mass:
        shift_slow_modes(problem, state, p)
    return k


def sample_numba(coef: np.ndarray, map_x: np.ndarray, map_y: np.ndarray, kernel: str) -> np.ndarray:
    """warping.sample_coefficients with the numba kernel: coef (H, W) or (C, H, W) at (map_x, map_y)."""
    src = _f32c(coef)
    flat = src.reshape((-1,) + src.shape[-2:])
    out = np.empty((flat.shape[0],) + map_x.shape, _F32)
    nw.warp_kernel(flat, _f32c(map_x), _f32c(map_y), KERNEL_CODES[kernel], out,
                   threads() > 1 and map_x.size >= PARALLEL_MIN_PIXELS)
    return out.reshape(coef.shape[:-2] + map_x.shape)


def bspline_prefilter_numba(img: np.ndarray) -> np.ndarray:
    """warping.bspline_prefilter with the numba kernel: B-spline coefficients of img (..., H, W), float32.

    Both axes run the column kernel over whole rows (unit stride, vectorised): the row pass on the
    transposed planes (a recursion along each row is latency-bound, one element at a time)."""
    shape = np.shape(img)
    h, w = shape[-2:]
    planes = np.asarray(img, dtype=_F32).reshape((-1, h, w))
    rows = scratch("prefilter.rows", (planes.shape[0], w, h))  # (N, W, H): rows as columns
    for p, dst in zip(planes, rows, strict=True):
        cv2.transpose(p, dst=dst)
    nw.bspline_columns(rows, BSPLINE_POLE, min(w, HORIZON))
    out = np.stack([cv2.transpose(p) for p in rows])
    nw.bspline_columns(out, BSPLINE_POLE, min(h, HORIZON))
    return out.reshape(shape)


def linearise_numba(i0: np.ndarray, source1: np.ndarray, grad_i0: np.ndarray | None, flow0: np.ndarray, scheme: str,
                    kernel: str = "bspline", warper: Warper | None = None, min_pixels: int | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """operators.linearise with one fused kernel (``warper`` is not used: the kernel samples itself); rows in
    parallel on levels of ``min_pixels`` pixels or more (None: LINEARISE_PARALLEL_MIN_PIXELS)."""
    h, w = i0.shape
    a = np.empty((2, h, w), _F32)
    c = np.empty((h, w), _F32)
    interpolated = scheme == "interpolated"
    parallel = parallel_at(h * w, LINEARISE_PARALLEL_MIN_PIXELS if min_pixels is None else min_pixels)
    rows, base = row_scratch(w)
    nw.linearise_kernel(_f32c(i0), _f32c(source1), _f32c(grad_i0) if interpolated else zero_rows(w)["g0"],
                        _f32c(flow0),
                        KERNEL_CODES[kernel], interpolated, a, c, rows, base, parallel)
    return a, c


def image_gradient_numba(img: np.ndarray, scheme: str, out: np.ndarray | None = None) -> np.ndarray:
    """operators.image_gradient with one kernel (nw.gradient_kernel) for a float32 C-contiguous image (H, W) and a
    float32 C-contiguous ``out`` (2, H, W) or none; anything else (a volume, another dtype or layout) goes to the
    reference. The same values bit for bit."""
    if (img.ndim != 2 or img.dtype != _F32 or not img.flags.c_contiguous
            or (out is not None and (out.dtype != _F32 or not out.flags.c_contiguous))):
        return image_gradient(img, scheme, out)
    if out is None:
        out = np.empty((2,) + img.shape, _F32)
    elif np.may_share_memory(img, out):
        raise ValueError("image_gradient: out overlaps the image")
    nw.gradient_kernel(img, scheme != "forward", out)
    return out


WARPER = Warper(sample_numba, bspline_prefilter_numba)
warp_numba = WARPER.warp
