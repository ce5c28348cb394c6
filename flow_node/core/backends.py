"""Choosing the per-warp solver and the warp: the numba kernels when importable (or asked for), else the
numpy reference."""

from __future__ import annotations

import logging
from typing import NamedTuple

from .errors import ConfigError
from .solver import LevelSolver, solve_numpy
from .warping import NUMPY_WARPER, Warper

log = logging.getLogger("flow_node")


class Backend(NamedTuple):
    """A resolved backend: its name, the level solver and the warper (same semantics in every backend)."""

    name: str
    solve: LevelSolver
    warper: Warper


NUMPY = Backend("numpy", solve_numpy, NUMPY_WARPER)


def numba_available() -> bool:
    """True when the numba backend can be imported."""
    try:
        from . import numba_backend  # noqa: F401
    except ImportError:
        return False
    return True


def select_backend(name: str, threads: int = 0) -> Backend:
    """Resolve ``auto``/``numpy``/``numba`` to a :class:`Backend` and log one line saying which.

    ``numba`` raises ConfigError when numba cannot be imported; ``auto`` falls back to numpy (with a
    warning naming the import error). ``threads`` caps the numba kernels' threads (0 = all cores).
    """
    if name == "numpy":
        log.info("flow_node backend: numpy (reference, requested)")
        return NUMPY
    try:
        from . import numba_backend
    except ImportError as exc:
        if name == "numba":
            raise ConfigError(f"backend 'numba' requested but numba is not importable: {exc}") from exc
        log.warning("flow_node backend: numpy (numba not importable: %s)", exc)
        return NUMPY
    used = numba_backend.set_threads(threads)
    log.info("flow_node backend: numba (%d thread%s, kernel cache %s)", used, "" if used == 1 else "s",
             numba_backend.cache_dir())
    return Backend("numba", numba_backend.solve_numba, numba_backend.WARPER)
