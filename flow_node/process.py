"""Process-wide settings that an executable of the package (``flow_node``, ``flow_bag``, ``flow_estimate``)
applies in its ``main()``. Never applied on import: a program that embeds the engine owns its process and
decides for itself (it can call these too)."""

from __future__ import annotations

import ctypes
import gc
import os

from . import numba_patch

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # glibc's mallopt parameter numbers (malloc.h)
KEEP_LIMIT = 256 << 20  # arrays up to this size come from the heap; twice it stays in the process when freed


# libgomp's default active spin-wait makes every parallel region cost milliseconds when cores are shared
# (measured: ~8-16 ms per region on a 2-vCPU VM, against ~15 us with passive waiting).
OMP_WAIT_POLICY = "passive"


def passive_thread_waits() -> None:
    """Let idle OpenMP threads (numba's threading layer) sleep instead of spinning: sets OMP_WAIT_POLICY for
    this process unless the user set it. libgomp reads it once, when it loads, i.e. when the first parallel
    numba kernel runs: call this before any flow is computed."""
    os.environ.setdefault("OMP_WAIT_POLICY", OMP_WAIT_POLICY)


def defer_kernel_bitcode() -> bool:
    """Patch numba (the one place the package does; numba_patch.py says what and why) so that reading a cached
    kernel skips parsing the LLVM bitcode stored beside its object code until a compilation links it in: a
    fresh process's first flow reads its 3-8 kernels in ~1/3 of the time. Only on the numba versions it was
    checked against (else numba's own read stays); returns whether it applies. Call before the first flow."""
    return numba_patch.install()


def skip_final_collection() -> None:
    """Let the interpreter's exit skip the garbage collection of every object alive now (``gc.freeze()``):
    call it once an executable's work is done. At exit Python clears its modules and then collects the
    cycles left, which with numba loaded (its typing registries, the kernels' libraries) is a traversal of
    some million objects: 0.1-0.2 s of a fresh ``flow_estimate`` on a 2-core VM, longer than a ``realtime``
    flow (docs/engine.md, "Compiled kernels"). Nothing else changes: atexit handlers run, objects without
    cycles are still freed by their reference counts (open files closed and flushed), and objects created
    later are collected as usual; only the frozen objects' cycles are left to the OS with the process."""
    gc.freeze()


def keep_freed_environ(limit_bytes: int = KEEP_LIMIT) -> dict[str, str]:
    """The same settings as :func:`keep_freed_memory`, as glibc's environment variables, for a process started
    by someone else (Dask's nanny starts the embedded cluster's workers with them; glibc reads them at start)."""
    return {"MALLOC_MMAP_THRESHOLD_": str(limit_bytes), "MALLOC_TRIM_THRESHOLD_": str(2 * limit_bytes)}


def keep_freed_memory(limit_bytes: int = KEEP_LIMIT) -> bool:
    """Serve arrays up to ``limit_bytes`` from the heap and keep freed heap memory in the process (glibc only;
    returns whether it applied).

    Every frame the engine allocates and frees arrays of 0.1-5 MB; with glibc's defaults each is a fresh
    mmap whose pages fault in on first touch, which cost ~3 ms per VGA frame in the grey conversion alone on
    a 2-core VM (docs/node.md, "Memory allocation"), and ~15 % of a ``flow_bag eval`` of a VGA bag with
    ``realtime`` (issue 12/14, ``git show a451d03:BENCHMARKS.md``). Memory stays bounded by the per-frame
    peak: what is kept is reused by the next frame."""
    try:
        libc = ctypes.CDLL("libc.so.6")
        return bool(libc.mallopt(_M_MMAP_THRESHOLD, limit_bytes)) and bool(libc.mallopt(_M_TRIM_THRESHOLD,
                                                                                         2 * limit_bytes))
    except (OSError, AttributeError):
        return False
