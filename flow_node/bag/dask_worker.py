"""Preload of the embedded cluster's worker processes (Dask's ``distributed.worker.preload``, set by
:func:`flow_node.bag.batch.local_cluster`; give it to workers of your own cluster with ``--preload
flow_node.bag.dask_worker``): Dask calls its ``dask_setup`` when a worker starts and its ``dask_teardown``
when a worker closes, right before the worker's process exits."""

from __future__ import annotations

import gc
from typing import Any

from ..process import defer_kernel_bitcode, keep_freed_memory, passive_thread_waits


def dask_setup(worker: Any) -> None:
    """The worker starts: keep freed memory as every flow_node executable does (flow_node/process.py). Dask's
    nanny starts workers with MALLOC_TRIM_THRESHOLD_=65536, under which every per-frame array is a fresh
    mmap (bag tasks ran up to 2x slower); the embedded cluster's workers also get it through their environment
    (batch.WORKER_ENV), a worker of someone else's cluster only through this. Idle numba threads sleep
    (process.passive_thread_waits) and cached kernels are read without parsing their bitcode
    (process.defer_kernel_bitcode), as in the executables."""
    keep_freed_memory()
    passive_thread_waits()
    defer_kernel_bitcode()


def dask_teardown(worker: Any) -> None:
    """The worker is closing and its process exits next: move every object to the permanent generation,
    so that the interpreter's finalization does not walk them all again in its collections. After a
    batch a worker process holds numba's, OpenCV's and matplotlib's objects; those collections took 1-4 s
    per process (measured in issue 14: `git show a451d03:BENCHMARKS.md`), and the batch waited for them in
    the cluster's close.
    The memory goes back to the system with the process either way."""
    gc.freeze()
