"""Preload of the embedded cluster's worker processes (Dask's ``distributed.worker.preload``, set by
:func:`flow_node.bag.batch.local_cluster`): Dask calls its ``dask_teardown`` when a worker closes,
right before the worker's process exits."""

from __future__ import annotations

import gc
from typing import Any


def dask_teardown(worker: Any) -> None:
    """The worker is closing and its process exits next: move every object to the permanent generation,
    so that the interpreter's finalization does not walk them all again in its collections. After a
    batch a worker process holds numba's, OpenCV's and matplotlib's objects; those collections took 1-4 s
    per process (measured: BENCHMARKS.md, issue 14), and the batch waited for them in the cluster's close.
    The memory goes back to the system with the process either way."""
    gc.freeze()
