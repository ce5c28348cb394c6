"""Scratch arrays reused from call to call: temporaries of one level (the warp source, frame 0's gradient,
the prefilter's transposed planes, the numba solver's extrapolated variables and the kernels' per-thread row
scratch) are requested here by name and shape instead of being allocated fresh on every call.

Why: it saves the allocation and a concatenation per level, and it keeps the engine's speed independent of
the allocator's state. In a loop of same-size calls glibc reuses the freed blocks (no page faults per call
measured), but a process whose allocator returns large freed blocks to the kernel pays for fresh zeroed pages
on every call: the warp source of a 640x480 level measured 4-7 ms that way against 0.5 ms (``git show
a451d03:BENCHMARKS.md``, "Engine speed, round 3"). Allocator settings themselves belong to an executable's
main(), not here.

The pool is per thread (threads never share an array: two flows computed at once in two threads, e.g. two
nodes in one process, each get their own) and bounded (MAX_ENTRIES, least recently used dropped first: a
stream of ever-changing frame sizes cannot grow it without limit, while the ~8 arrays per pyramid level of a
15-level preset stay in it from frame to frame). Contents are undefined, as with np.empty. A caller owns a
scratch array only until it, or anything it calls in the same thread, asks for the same name and shape
again: use one only for temporaries that do not outlive the call that requested them, and never pass one
as an ``out=`` that aliases an input.
"""

from __future__ import annotations

import math
import threading

import numpy as np

MAX_ENTRIES = 256  # per thread; a frame of a 15-level preset uses ~120 (numba backend, interpolated scheme)
_local = threading.local()


def scratch(name: str, shape: tuple[int, ...], dtype: type = np.float32) -> np.ndarray:
    """The calling thread's scratch array ``name`` of ``shape`` and ``dtype`` (C-contiguous, contents
    undefined); the same array on every request with the same key in this thread while it stays among the
    MAX_ENTRIES most recently requested."""
    pool = getattr(_local, "pool", None)
    if pool is None:
        pool = _local.pool = {}
    key = (name, tuple(shape), np.dtype(dtype))
    buf = pool.pop(key, None)  # re-inserted below: the dict's order is the order of last use
    if buf is None:
        while len(pool) >= MAX_ENTRIES:
            del pool[next(iter(pool))]
        buf = np.empty(key[1], key[2])
    pool[key] = buf
    return buf


Parts = tuple[tuple[str, tuple[int, ...]], ...]  # (name, shape) of each view, in order


def scratch_parts(name: str, parts: Parts) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The calling thread's float32 scratch array ``name`` (1-D, as long as the ``parts`` together) and its
    named C-contiguous views of the shapes in ``parts`` ((name, shape) pairs, in order). The views are cut once
    per array and kept beside the pool for this thread, so a caller on a hot path pays one :func:`scratch`
    request, not a reshape per part; they are those of the array the pool returns now (a dropped and
    re-allocated array gets new ones)."""
    views = getattr(_local, "views", None)
    if views is None:
        views = _local.views = {}
    hit = views.get((name, parts))
    flat = scratch(name, hit[0].shape if hit is not None else (sum(math.prod(shape) for _, shape in parts),))
    if hit is not None and hit[0] is flat:
        return flat, hit[1]
    if len(views) >= MAX_ENTRIES:
        views.clear()
    out, start = {}, 0
    for part, shape in parts:
        size = math.prod(shape)
        out[part] = flat[start:start + size].reshape(shape)
        start += size
    views[(name, parts)] = (flat, out)
    return flat, out


PoolKey = tuple[str, tuple[int, ...], np.dtype]


def pooled() -> dict[PoolKey, np.ndarray]:
    """A snapshot of the calling thread's pool: (name, shape, dtype) -> its array, least recently requested
    first (a new dict; the arrays are the pool's own)."""
    return dict(getattr(_local, "pool", {}))
