"""The volume kernels load only inside the arrays they are given, whatever the model's flags (issue 29's rule,
numba_kernels.py and numba_volume.py docstrings).

A flag's branch in a pixel loop becomes AVX-512 masked loads of the other branch's operands; a masked-off lane
on a page that is not mapped (or not touched yet) costs a microcode assist per vector step. What a model or
scheme leaves unused (w_bar without w, tv_l2's z, gi0 without the interpolated scheme; the 1x1x1 dummies of w
and s) is handed to the kernels here right before an inaccessible region as long as the whole grid's arrays:
the solve and the linearisation must take about their ordinary time and give the same bits.

The tree before (1x1x1 dummies indexed at (k, i, j)) passes too (1.02-1.06x): as compiled there, the flags'
branches stay jumps (the dual pass's masked loads of w_bar sit behind a test of ``reg``), so no filler load is
issued. The test can fail: a mutant reading the zero row unclamped under a per-voxel condition (``(reg - 1) *
f0 * f0 > 0``: masked loads) took 12.5x the time here; the same mutant with the clamped index 0.92x.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable

import numpy as np
import pytest
from test_kernel_bounds import Guarded

from flow_node.core import numba_volume
from flow_node.core.models import MODEL_SPECS
from flow_node.core.solver import PDState, Problem, SolveParams

N = 48  # 48^3 voxels: under PARALLEL_MIN_PIXELS, the serial kernels (one thread, steadier timing)
GRID = (N, N, N)


def guarding(kernel: Callable[..., object], guard: Guarded) -> Callable[..., object]:
    """``kernel`` with every array argument that is not a whole-grid array (a dummy or a zero row) replaced by
    a copy that ends right before an inaccessible region as large as 27 grid arrays."""

    def call(*args: object) -> object:
        moved = [guard.like(x, 27 * 4 * N ** 3) if isinstance(x, np.ndarray) and x.shape[-3:] != GRID else x
                 for x in args]
        return kernel(*moved)

    return call


def _best_ratio(run: Callable[[], tuple[float, np.ndarray]], run_guarded: Callable[[], tuple[float, np.ndarray]]
                ) -> float:
    """Median time of ``run_guarded`` over ``run`` (5 interleaved pairs; a busy moment hits both alike); both
    must give the same bits."""
    run()  # loads the kernels
    ordinary, guarded = [], []
    for _ in range(5):
        t, out = run()
        ordinary.append(t)
        t, out_guarded = run_guarded()
        guarded.append(t)
        assert np.array_equal(out_guarded, out)
    return statistics.median(guarded) / statistics.median(ordinary)


@pytest.mark.parametrize("model", ["l1_tv", "l1_tv_l2"])
def test_a_volume_solve_with_guarded_fillers_is_as_fast_and_the_same(model: str,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(4)
    problem = Problem((0.2 * rng.standard_normal((3,) + GRID)).astype(np.float32),
                      (0.05 * rng.standard_normal(GRID)).astype(np.float32))
    start = PDState.zeros(MODEL_SPECS[model], GRID)
    start.v = (0.5 * rng.standard_normal((3,) + GRID)).astype(np.float32)
    params = SolveParams(MODEL_SPECS[model], 0.06, 0.3, "isotropic", 8, 0.0)
    plain = numba_volume.iterate

    def solve(kernel: Callable[..., object]) -> tuple[float, np.ndarray]:
        monkeypatch.setattr(numba_volume, "iterate", kernel)
        st = PDState(start.v.copy(), start.y.copy(), None if start.w is None else start.w.copy())
        t0 = time.perf_counter()
        numba_volume.solve_numba(problem, st, params)
        return time.perf_counter() - t0, st.v

    guarded = guarding(plain, Guarded())
    ratio = _best_ratio(lambda: solve(plain), lambda: solve(guarded))
    assert ratio < 2.0, f"the {model} solve on guarded fillers took {ratio:.1f}x the time: a kernel loads past one"


def test_a_linearisation_without_gi0_with_a_guarded_filler_is_as_fast_and_the_same(
        monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(5)
    i0 = rng.random(GRID, np.float32)
    src = rng.random((4,) + GRID, np.float32)
    v0 = (2.0 * rng.standard_normal((3,) + GRID)).astype(np.float32)
    plain = numba_volume.linearise_ser

    def linearise(kernel: Callable[..., object]) -> tuple[float, np.ndarray]:
        monkeypatch.setattr(numba_volume, "linearise_ser", kernel)
        t0 = time.perf_counter()
        for _ in range(3):
            a, c = numba_volume.linearise_numba(i0, src, v0, None)
        return time.perf_counter() - t0, np.concatenate([a, c[None]])

    guarded = guarding(plain, Guarded())
    ratio = _best_ratio(lambda: linearise(plain), lambda: linearise(guarded))
    assert ratio < 2.0, f"the linearisation with a guarded gi0 filler took {ratio:.2f}x the time"
