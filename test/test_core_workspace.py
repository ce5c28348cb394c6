"""The engine's scratch arrays (workspace.py): reused per name and shape, never shared between threads, bounded."""

from __future__ import annotations

import threading

import numpy as np

from flow_node.core import workspace
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
    assert len(workspace._local.pool) <= workspace.MAX_ENTRIES
