"""Choosing the per-warp solver: the numba kernels when importable (or asked for), else the numpy reference."""

from __future__ import annotations

import logging

from .errors import ConfigError
from .solver import LevelSolver, solve_numpy

log = logging.getLogger("flow_node")


def numba_available() -> bool:
    """True when the numba backend can be imported."""
    try:
        from . import numba_backend  # noqa: F401
    except ImportError:
        return False
    return True


def select_backend(name: str, threads: int = 0) -> tuple[str, LevelSolver]:
    """Resolve ``auto``/``numpy``/``numba`` to (backend name, level solver).

    ``numba`` raises ConfigError when numba cannot be imported; ``auto`` falls back to numpy.
    """
    if name == "numpy":
        return "numpy", solve_numpy
    try:
        from . import numba_backend
    except ImportError as exc:
        if name == "numba":
            raise ConfigError(f"backend 'numba' requested but numba is not importable: {exc}") from exc
        return "numpy", solve_numpy
    numba_backend.set_threads(threads)
    return "numba", numba_backend.solve_numba
