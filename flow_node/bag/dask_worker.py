"""Preload of the embedded cluster's worker processes (Dask's ``distributed.worker.preload``, set by
:func:`flow_node.bag.batch.local_cluster`): Dask calls ``dask_setup`` when a worker starts and
``dask_teardown`` when it closes, right before its process exits."""

from __future__ import annotations

import gc
from typing import Any


def dask_setup(worker: Any) -> None:
    """Nothing to prepare: the first task imports the engine and loads the JIT cache."""


def dask_teardown(worker: Any) -> None:
    """The worker is closing and its process exits next: move every object to the permanent generation,
    so that the interpreter's finalization does not walk them all again in its collections. After a
    batch a worker process holds numba's, OpenCV's and matplotlib's objects; those collections took 1-4 s
    per process (measured: BENCHMARKS.md, issue 14), and the batch waited for them in the cluster's close.
    The memory goes back to the system with the process either way."""
    gc.freeze()
