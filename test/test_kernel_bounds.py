"""The iteration kernels (and the census form's) load only inside the arrays they are given, whatever the model's
flags (issue 29).

LLVM turns a flag's branch in a pixel loop (quadratic data term, mass, extended model) into AVX-512 masked
loads; a masked-off lane whose address is on a page that is not mapped, or not touched yet, costs a
microcode assist on every vector step. A 2-plane data term read as the quadratic term's 5 planes did that in
a fresh process (its heap's top untouched): the first flow of ``quality`` ran the primal pass ~8x slower.
Here the problem's arrays end right before an inaccessible page: the solve must take about the time it
takes on ordinary arrays (3.4x slower before the planes were clamped) and give the same bits.
"""

from __future__ import annotations

import ctypes
import mmap
import statistics
import time

import numpy as np
import pytest

from flow_node.core import numba_backend
from flow_node.core.census import CENSUS
from flow_node.core.models import MODEL_SPECS
from flow_node.core.numba_backend import solve_numba, zero_rows
from flow_node.core.numba_census import census_form_numba, level_signature_numba
from flow_node.core.solver import PDState, Problem, SolveParams

H, W = 240, 320  # serial kernels (under PARALLEL_MIN_PIXELS): one thread, steadier timing
_PROT_NONE = 0


class Guarded:
    """Float32 arrays each followed by inaccessible pages (as many bytes as 4 more arrays of its size, so
    that reading planes past its end hits them); the mappings live as long as this object."""

    def __init__(self) -> None:
        self.maps: list[mmap.mmap] = []
        self.libc = ctypes.CDLL("libc.so.6", use_errno=True)
        self.libc.mprotect.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int]

    def like(self, x: np.ndarray, guard_bytes: int = 0) -> np.ndarray:
        """A copy of ``x`` (float32, C order) whose last byte is the last one before the guard (at least
        ``guard_bytes`` long)."""
        page = mmap.PAGESIZE
        n = x.size * 4
        data_pages, guard_pages = -(-n // page), -(-max(4 * n, guard_bytes) // page) + 1
        mm = mmap.mmap(-1, (data_pages + guard_pages) * page)
        self.maps.append(mm)
        raw = np.frombuffer(mm, np.uint8)
        end = data_pages * page
        if self.libc.mprotect(raw.ctypes.data + end, guard_pages * page, _PROT_NONE) != 0:
            pytest.skip(f"mprotect failed (errno {ctypes.get_errno()})")
        out = raw[end - n:end].view(np.float32).reshape(x.shape)
        out[...] = x
        return out


def _problem(rng: np.random.Generator) -> tuple[Problem, PDState]:
    f32 = np.float32
    a = (0.2 * rng.standard_normal((2, H, W))).astype(f32)
    c = (0.05 * rng.standard_normal((H, W))).astype(f32)
    state = PDState.zeros(MODEL_SPECS["l1_tv"], (H, W))
    state.v = (0.5 * rng.standard_normal((2, H, W))).astype(f32)
    return Problem(a, c), state


def _solve(problem: Problem, state: PDState, params: SolveParams) -> tuple[float, np.ndarray]:
    st = PDState(state.v.copy(), state.y.copy())
    start = time.perf_counter()
    solve_numba(problem, st, params)
    return time.perf_counter() - start, st.v


def test_a_problem_before_an_inaccessible_page_solves_as_fast_and_the_same() -> None:
    problem, state = _problem(np.random.default_rng(3))
    guard = Guarded()
    edge = Problem(guard.like(problem.a), guard.like(problem.c))
    params = SolveParams(MODEL_SPECS["l1_tv"], 0.05, 0.3, "isotropic", 30, 0.0)
    _solve(problem, state, params)  # loads the kernels
    ordinary, guarded = [], []
    for _ in range(5):  # interleaved: a busy moment of a shared machine hits both alike
        t, v_ordinary = _solve(problem, state, params)
        ordinary.append(t)
        t, v_guarded = _solve(edge, state, params)
        guarded.append(t)
    assert np.array_equal(v_guarded, v_ordinary)
    ratio = statistics.median(guarded) / statistics.median(ordinary)
    assert ratio < 2.0, f"the solve on guarded arrays took {ratio:.1f}x the time: a kernel loads past an array"


def test_zero_rows_are_written_zeros_of_the_documented_shapes() -> None:
    rows = zero_rows(37)
    assert set(rows) == set(numba_backend.ZERO_ROWS)
    for name, arr in rows.items():
        assert arr.shape == numba_backend.ZERO_ROWS[name](37) and arr.dtype == np.float32, name
        assert arr.flags.c_contiguous and not np.any(arr), name
    rows["p"][...] = 5.0  # contents are the caller's until the next request: the next one zeroes them again
    again = zero_rows(37)
    assert np.shares_memory(again["p"], rows["p"]) and not np.any(again["p"])
    v = np.zeros((2, 9, 37), np.float32)
    _, w_bar, _, zero_b = numba_backend.work_buffers(v, None, again)
    assert w_bar is again["w_bar"] and zero_b is again["b"]


def test_the_census_form_before_an_inaccessible_page_is_as_fast_and_the_same() -> None:
    """The census kernel (numba_census.census_kernel: the warp's taps and the form's flags) reads only inside
    frame 0's signatures, frame 1's coefficients and channels and the flow."""
    rng = np.random.default_rng(5)
    i0, i1 = (rng.random((H, W), dtype=np.float32) for _ in range(2))
    v0 = (2.0 * rng.standard_normal((2, H, W))).astype(np.float32)
    v0[0, :8, :8] = -50.0  # a corner outside the image
    args = [level_signature_numba(i0, CENSUS)[0], None, numba_backend.WARPER.coefficients(i1[None], "bspline"),
            i1[None], v0]
    guard = Guarded()
    edge = [a if a is None else guard.like(a) for a in args]

    def form(arrays: list[np.ndarray | None]) -> tuple[float, np.ndarray]:
        start = time.perf_counter()
        out = census_form_numba(*arrays, "bspline", True, CENSUS)
        return time.perf_counter() - start, out

    with numba_backend.thread_count(1):
        form(args)  # loads the kernel
        ordinary, guarded = [], []
        for _ in range(5):  # interleaved
            t, q_ordinary = form(args)
            ordinary.append(t)
            t, q_guarded = form(edge)
            guarded.append(t)
    assert np.array_equal(q_guarded, q_ordinary)
    ratio = statistics.median(guarded) / statistics.median(ordinary)
    assert ratio < 2.0, f"the census form on guarded arrays took {ratio:.1f}x the time: a kernel loads past an array"
