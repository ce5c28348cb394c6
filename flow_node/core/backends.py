"""Choosing the per-warp solver and the warp: the numba kernels when importable (or asked for), else the
numpy reference."""

from __future__ import annotations

import logging
from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext
from functools import partial
from types import ModuleType
from typing import Any, NamedTuple

import numpy as np

from .census import CensusForm, LevelSignature, census_form, level_signature, median_contrast, reliability
from .census_noise import noise_sigma
from .confidence import Confidence, ConfidenceAt, confidence, confidence_at
from .densify import push_pull, splat_forward
from .edges import EdgeWeight, edge_weight
from .errors import ConfigError
from .fusion import Fuse, LevelPlanes, fuse, level_planes
from .initialise import Consistent, equalised, forward_backward_consistent
from .operators import ImageGradient, Linearise, image_gradient, linearise
from .photometric import Reliability, sorted_sample
from .solver import LevelSolver, solve_numpy
from .warping import NUMPY_WARPER, Warper
from .wmedian import WeightedMedian, weighted_median

log = logging.getLogger("flow_node")


def _single_threaded(threads: int) -> AbstractContextManager[object]:
    """The numpy references' :attr:`Backend.on_threads`: nothing to bind (OpenCV keeps its own pool)."""
    return nullcontext()


class Backend(NamedTuple):
    """A resolved backend: its name, the level solver, the warper, the linearisation of one warp, the
    reliability figure (census.reliability, whatever the data term), the fusion and its forward-backward check,
    the census data term's level signature and per-warp form (grey or colour channels alike), the per-pixel
    confidence of a flow, the stream stage's forward splat (temporal.predict), the photometric stage's sorted
    sample of a frame (photometric.sorted_sample; the same array in every backend), the data term's image
    gradient (operators.image_gradient), the stream stage's hole fill (densify.push_pull), the fusion's cost
    planes of a level's frame (fusion.level_planes), the census initialisation's mid-ranks of a frame
    (initialise.equalised), a census level's contrast (census.median_contrast), a frame's noise for the census
    noise floor (census_noise.noise_sigma) and the edge-weighted TV's weight of a level (edges.edge_weight) (same
    semantics in every
    backend; the defaults are the numpy references, the linearisation on ``warper``); the threads its kernels
    run on and the context that binds them (:meth:`running`).
    """

    name: str
    solve: LevelSolver
    warper: Warper
    linearise: Linearise = linearise
    reliability: Reliability = reliability
    fuse: Fuse = fuse
    consistent: Consistent = forward_backward_consistent
    signature: LevelSignature = level_signature
    census_form: CensusForm = census_form
    confidence: Confidence = confidence
    threads: int = 1
    on_threads: Callable[[int], AbstractContextManager[object]] = _single_threaded
    splat: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]] = splat_forward
    confidence_at: ConfidenceAt = confidence_at  # the confidence at pixel points only (the fits' samples)
    sample: Callable[[np.ndarray], np.ndarray] = sorted_sample  # the photometric stage's sorted sample of a frame
    gradient: ImageGradient = image_gradient  # the data term's image gradient (operators.image_gradient)
    fill: Callable[[np.ndarray, np.ndarray], np.ndarray] = push_pull  # the stream stage's hole fill (densify.push_pull)
    cost_planes: LevelPlanes = level_planes  # what the fusion compares of a level's frame (fusion.level_planes)
    ranks: Callable[[np.ndarray], np.ndarray] = equalised  # a frame's mid-ranks for census's sources (equalised)
    contrast: Callable[[np.ndarray], float] = median_contrast  # a census level's contrast (census.median_contrast)
    noise: Callable[[np.ndarray], float] = noise_sigma  # a frame's white-noise std (census_noise.noise_sigma)
    edge_weight: EdgeWeight = edge_weight  # the edge-weighted TV's g of a level (edges.edge_weight)
    weighted_median: WeightedMedian = weighted_median  # the weighted median after a warp (wmedian.weighted_median)

    def resolved(self) -> Backend:
        """This backend with each :class:`Deferred` field replaced by the function it stands for (importing
        that function's module now)."""
        return self._replace(**{f: getattr(self, f).function() for f in self._fields
                                if isinstance(getattr(self, f), Deferred)})

    def running(self) -> AbstractContextManager[object]:
        """The context each estimate runs in: the backend's kernels on its ``threads``, bound to the calling
        thread for the block (not a process-wide setting: two estimators with different ``threads`` each run
        with their own, also in one thread one after the other)."""
        return self.on_threads(self.threads)


NUMPY = Backend("numpy", solve_numpy, NUMPY_WARPER)


class Deferred:
    """A numba backend function whose module is imported on the first call, not when the backend is
    selected: the census, confidence, stream-splat and edge-weight kernels, which a call without the census data
    term, the confidence, a stream or the edge-weighted TV does not run (and the sort of the photometric stage's
    sample, numba_sort.py, which every call runs: deferred like the others, so that selecting a backend stays
    cheap). Importing a
    kernel module creates its dispatchers, and numba checks each one's cache folder by writing a file there
    (1-2 ms a dispatcher on a loaded machine): these 18 dispatchers cost a fresh process's first call 25-50 ms
    at load 6-9 before (docs/engine.md, "Compiled kernels")."""

    __slots__ = ("_load", "_name", "_function")

    def __init__(self, load: Callable[[], ModuleType], name: str) -> None:
        self._load, self._name = load, name
        self._function: Callable[..., Any] | None = None

    def function(self) -> Callable[..., Any]:
        """The function this stands for (its module imported on the first request)."""
        if self._function is None:
            self._function = getattr(self._load(), self._name)
        return self._function

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self.function()(*args, **kwargs)

    def __reduce__(self) -> tuple[Any, ...]:
        return Deferred, (self._load, self._name)

    def __repr__(self) -> str:
        return f"Deferred({self._load.__name__.lstrip('_')}.{self._name})"


def _numba_census() -> ModuleType:
    from . import numba_census
    return numba_census


def _numba_confidence() -> ModuleType:
    from . import numba_confidence
    return numba_confidence


def _numba_temporal() -> ModuleType:
    from . import numba_temporal
    return numba_temporal


def _numba_edges() -> ModuleType:
    from . import numba_edges
    return numba_edges


def _numba_wmedian() -> ModuleType:
    from . import numba_wmedian
    return numba_wmedian


def _numba_sort() -> ModuleType:
    from . import numba_sort
    return numba_sort


def numba_import_error() -> str | None:
    """Why the numba backend cannot be imported (the ImportError's text), or None when it can."""
    try:
        from . import numba_backend  # noqa: F401
    except ImportError as exc:
        return str(exc)
    return None


def numba_available() -> bool:
    """True when the numba backend can be imported."""
    return numba_import_error() is None


def fallback_warning(requested: str, used: str) -> str | None:
    """A one-line warning when ``auto`` had to fall back to the numpy reference, else None.

    ``requested`` is the config's ``backend``, ``used`` the backend selected. Asking for numpy is no
    reason to warn; running it because numba is missing is (3-5x slower: ``git show a451d03:BENCHMARKS.md``).
    """
    if requested != "auto" or used != "numpy":
        return None
    reason = numba_import_error() or "numba backend unavailable"
    return (f"numba not importable ({reason}): running the numpy reference backend, 3-5x slower; "
            "install numba (README, 'ROS 2 workspace')")


def select_backend(name: str, threads: int = 0, parallel_min_pixels: int = 0) -> Backend:
    """Resolve ``auto``/``numpy``/``numba`` to a :class:`Backend` and log one line saying which.

    ``numba`` raises ConfigError when numba cannot be imported; ``auto`` falls back to numpy (with a
    warning naming the import error). ``threads`` caps the numba kernels' threads (0 = all cores).
    ``parallel_min_pixels`` > 0: the numba solver and linearisation run their parallel kernels on levels of
    that many pixels or more (0: numba_backend's defaults; the results are the same either way).
    """
    if name == "numpy":
        log.info("flow_node backend: numpy (reference, requested)")
        return NUMPY
    try:
        from . import numba_backend, numba_fusion, numba_judge
    except ImportError as exc:
        if name == "numba":
            raise ConfigError(f"backend 'numba' requested but numba is not importable: {exc}") from exc
        log.warning("flow_node backend: numpy (numba not importable: %s)", exc)
        return NUMPY
    used = numba_backend.resolve_threads(threads)
    log.info("flow_node backend: numba (%d thread%s, kernel cache %s)", used, "" if used == 1 else "s",
             numba_backend.cache_dir())
    solve, linearise_ = numba_backend.solve_numba, numba_backend.linearise_numba
    if parallel_min_pixels > 0:
        solve, linearise_ = (partial(f, min_pixels=parallel_min_pixels) for f in (solve, linearise_))
    return Backend("numba", solve, numba_backend.WARPER, linearise_,
                   numba_judge.reliability_numba, numba_fusion.fuse_numba, numba_fusion.consistent_numba,
                   Deferred(_numba_census, "level_signature_numba"), Deferred(_numba_census, "census_form_numba"),
                   Deferred(_numba_confidence, "confidence_numba"), used,
                   numba_backend.thread_count, splat=Deferred(_numba_temporal, "splat_numba"),
                   confidence_at=Deferred(_numba_confidence, "confidence_at_numba"),
                   sample=Deferred(_numba_sort, "sorted_sample_numba"), gradient=numba_backend.image_gradient_numba,
                   fill=Deferred(_numba_temporal, "push_pull_numba"),
                   cost_planes=numba_fusion.planes_numba, ranks=Deferred(_numba_sort, "ranks_numba"),
                   contrast=Deferred(_numba_census, "median_contrast_numba"),
                   noise=Deferred(_numba_sort, "noise_sigma_numba"),
                   edge_weight=Deferred(_numba_edges, "edge_weight_numba"),
                   weighted_median=Deferred(_numba_wmedian, "weighted_median_numba"))
