"""The engine's scratch arrays (workspace.py): reused per name and shape, never shared between threads, bounded."""

from __future__ import annotations

import threading

import numpy as np

from flow_node.core import workspace
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig
from flow_node.core.workspace import scratch


def test_same_key_same_array_other_key_other_array() -> None:
    a = scratch("test.a", (2, 5, 7))
    assert a.shape == (2, 5, 7) and a.dtype == np.float32 and a.flags.c_contiguous
    assert scratch("test.a", (2, 5, 7)) is a
    assert scratch("test.a", (2, 5, 8)) is not a
    assert scratch("test.b", (2, 5, 7)) is not a
    assert scratch("test.a", (2, 5, 7), np.int32).dtype == np.int32


def test_threads_get_their_own_arrays() -> None:
    mine = scratch("test.thread", (4, 4))
    theirs: list[np.ndarray] = []
    t = threading.Thread(target=lambda: theirs.append(scratch("test.thread", (4, 4))))
    t.start()
    t.join()
    assert theirs[0] is not mine and scratch("test.thread", (4, 4)) is mine


def test_the_pool_is_bounded() -> None:
    for k in range(3 * workspace.MAX_ENTRIES):
        scratch("test.many", (k + 1,))
    assert len(workspace.pooled()) <= workspace.MAX_ENTRIES


def test_arrays_in_use_stay_while_other_sizes_come_and_go() -> None:
    """Least recently used first: an array requested on every frame is kept however many other sizes pass
    through the pool (dropping everything when full would reallocate it every MAX_ENTRIES requests)."""
    kept = scratch("test.kept", (3, 4))
    for k in range(3 * workspace.MAX_ENTRIES):
        scratch("test.passing", (k + 1,))
        assert scratch("test.kept", (3, 4)) is kept


def test_a_frame_of_a_15_level_preset_fits_in_the_pool() -> None:
    """Frame after frame the engine gets the same scratch arrays back: the second frame allocates none, on
    the preset with the most levels (balanced: 15, interpolated gradient, numba backend)."""
    rng = np.random.default_rng(2)
    i0, i1 = rng.random((2, 400, 420)).astype(np.float32)
    est = FlowEstimator(FlowConfig.preset("balanced").replace(backend="numba", iterations=1, warps=1))
    res = est.estimate(i0, i1)
    assert len(res.stats.iterations) == 15
    before = workspace.pooled()
    est.estimate(i1, i0)
    after = workspace.pooled()
    assert after.keys() == before.keys() and all(after[k] is before[k] for k in before)


def test_scratch_parts_cuts_one_array_into_named_views_once() -> None:
    parts = (("a", (2, 3)), ("b", (4,)))
    flat, views = workspace.scratch_parts("test.parts", parts)
    assert flat.shape == (10,) and flat.dtype == np.float32
    assert views["a"].shape == (2, 3) and views["b"].shape == (4,)
    flat[:] = np.arange(10)
    assert views["a"].ravel().tolist() == list(range(6)) and views["b"].tolist() == [6, 7, 8, 9]
    again, views2 = workspace.scratch_parts("test.parts", parts)
    assert again is flat and views2 is views  # the same views, not cut again
    other, views3 = workspace.scratch_parts("test.parts", (("a", (5,)),))
    assert other is not flat and views3["a"].base is other
