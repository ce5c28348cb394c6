"""The numba backend against the numpy reference (the oracle), and backend selection.

Every model x TV norm x Bregman term runs the same fixed number of primal-dual iterations from the same
random state in both backends; all primal and dual variables must agree to ~1e-5. One compiled kernel
specialisation serves all cases, so the JIT cost (cold cache) is paid once for the whole file.
"""

from __future__ import annotations

import contextlib
import inspect
import logging
import sys
import threading
from collections.abc import Iterator

import numba
import numpy as np
import pytest
from synth import constant_flow, interior, pair_from_flow, rotation_flow, texture

from flow_node.core import numba_backend
from flow_node.core.api import FlowEstimator
from flow_node.core.backends import NUMPY, select_backend
from flow_node.core.census import census_form, level_signature, median_contrast
from flow_node.core.census import reliability as census_reliability
from flow_node.core.census_noise import noise_sigma
from flow_node.core.confidence import confidence, confidence_at
from flow_node.core.config import MODELS, FlowConfig
from flow_node.core.densify import push_pull, splat_forward
from flow_node.core.edges import edge_weight
from flow_node.core.errors import ConfigError
from flow_node.core.fusion import fuse, level_planes
from flow_node.core.initialise import equalised, forward_backward_consistent
from flow_node.core.metrics import aee
from flow_node.core.models import MODEL_SPECS
from flow_node.core.numba_backend import WARPER, image_gradient_numba, linearise_numba, solve_numba
from flow_node.core.numba_census import census_form_numba, level_signature_numba, median_contrast_numba
from flow_node.core.numba_confidence import confidence_at_numba, confidence_numba
from flow_node.core.numba_edges import edge_weight_numba
from flow_node.core.numba_fusion import consistent_numba, fuse_numba, planes_numba
from flow_node.core.numba_judge import reliability_numba as census_reliability_numba
from flow_node.core.numba_sort import noise_sigma_numba, ranks_numba, sorted_sample_numba
from flow_node.core.numba_temporal import push_pull_numba, splat_numba
from flow_node.core.numba_wmedian import weighted_median_numba
from flow_node.core.operators import image_gradient, linearise
from flow_node.core.photometric import sorted_sample
from flow_node.core.solver import CHECK_EVERY, PDState, Problem, SolveParams, solve_numpy
from flow_node.core.warping import NUMPY_WARPER
from flow_node.core.wmedian import weighted_median

H, W = 40, 56
ITERATIONS = 40
AGREE = 1e-5  # max abs difference of any variable after ITERATIONS (float32 round-off is ~1e-7)


def random_case(model: str, bregman: bool, seed: int) -> tuple[Problem, PDState]:
    """A random linearised problem and a random (non-zero) starting state, as after a previous warp."""
    rng = np.random.default_rng(seed)
    f32 = np.float32
    a = (0.2 * rng.standard_normal((2, H, W))).astype(f32)
    a[:, 5:9, 10:20] = 0.0  # textureless patch: |a| = 0 branch of the L1 prox
    c = (0.05 * rng.standard_normal((H, W))).astype(f32)
    b = (0.3 * rng.standard_normal((2, H, W))).astype(f32) if bregman else None
    st = PDState.zeros(MODEL_SPECS[model], (H, W))
    st.v = (0.5 * rng.standard_normal((2, H, W))).astype(f32)
    st.y = np.clip(0.4 * rng.standard_normal(st.y.shape), -0.7, 0.7).astype(f32)
    if st.w is not None:
        st.w = (0.1 * rng.standard_normal(st.w.shape)).astype(f32)
    if st.z is not None:
        st.z = (0.1 * rng.standard_normal(st.z.shape)).astype(f32)
    return Problem(a, c, b), st


def copy_state(st: PDState) -> PDState:
    return PDState(*(None if x is None else x.copy() for x in (st.v, st.y, st.w, st.z)))


def variables(st: PDState) -> list[np.ndarray]:
    return [x for x in (st.v, st.y, st.w, st.z) if x is not None]


@pytest.mark.parametrize("bregman", [False, True], ids=["plain", "bregman"])
@pytest.mark.parametrize("tv_norm", ["isotropic", "anisotropic"])
@pytest.mark.parametrize("model", MODELS)
def test_numba_matches_numpy(model: str, tv_norm: str, bregman: bool) -> None:
    prob, st0 = random_case(model, bregman, seed=MODELS.index(model))
    alpha = 0.002 if model.startswith("l2") else 0.05  # data terms of comparable pull on v
    params = SolveParams(MODEL_SPECS[model], alpha, 0.3, tv_norm, ITERATIONS, 0.0)
    ref, fast = copy_state(st0), copy_state(st0)
    assert solve_numpy(prob, ref, params) == ITERATIONS
    assert solve_numba(prob, fast, params) == ITERATIONS
    for r, f, s in zip(variables(ref), variables(fast), variables(st0), strict=True):
        assert f.shape == r.shape and f.dtype == np.float32
        assert np.abs(r - s).max() > 1e-2  # the iteration really moved every variable
        np.testing.assert_allclose(f, r, rtol=0, atol=AGREE)


def test_disagreement_is_detected() -> None:
    """Sanity of the comparison above: a different regulariser weight is far outside AGREE."""
    prob, st0 = random_case("l1_tv", False, seed=7)
    spec = MODEL_SPECS["l1_tv"]
    ref, fast = copy_state(st0), copy_state(st0)
    solve_numpy(prob, ref, SolveParams(spec, 0.05, 0.3, "isotropic", ITERATIONS, 0.0))
    solve_numba(prob, fast, SolveParams(spec, 0.06, 0.3, "isotropic", ITERATIONS, 0.0))
    assert np.abs(ref.v - fast.v).max() > 100 * AGREE


@pytest.mark.parametrize("model", ["l1_tv", "l2_l2"])
def test_same_early_stop(model: str) -> None:
    """The stopping rule (RMS update below tolerance, checked every CHECK_EVERY) stops both at the same k."""
    prob, st0 = random_case(model, False, seed=11)
    params = SolveParams(MODEL_SPECS[model], 0.05, 0.3, "isotropic", 500, 2e-3)
    ref, fast = copy_state(st0), copy_state(st0)
    k_ref = solve_numpy(prob, ref, params)
    k_fast = solve_numba(prob, fast, params)
    assert k_ref == k_fast
    assert k_ref % CHECK_EVERY == 0 and CHECK_EVERY <= k_ref < 500
    np.testing.assert_allclose(fast.v, ref.v, rtol=0, atol=AGREE)


def test_parallel_and_serial_kernels_agree() -> None:
    """Large levels run the prange kernels, small ones the serial variant (the threshold ``min_pixels``):
    the same numbers either way, bit for bit (each pixel's update is the same arithmetic)."""
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("one core: no parallel kernels")
    prob, st0 = random_case("l1_tv_tv", True, seed=3)
    params = SolveParams(MODEL_SPECS["l1_tv_tv"], 0.05, 0.3, "isotropic", 20, 0.0)
    iterate, seen = numba_backend.nk.iterate, []
    parallel = list(inspect.signature(iterate.py_func).parameters).index("parallel")
    states: dict[int | None, PDState] = {}
    with numba_backend.thread_count(2):
        for min_pixels in (0, H * W, H * W + 1, None):
            states[min_pixels] = copy_state(st0)
            with _spy_parallel(iterate, parallel, seen):
                solve_numba(prob, states[min_pixels], params, min_pixels=min_pixels)
    assert seen == [True, True, False, False]  # None: PARALLEL_MIN_PIXELS, above this level's H * W
    for min_pixels in (H * W, H * W + 1, None):
        for p, s in zip(variables(states[0]), variables(states[min_pixels]), strict=True):
            np.testing.assert_array_equal(p, s)


@contextlib.contextmanager
def _spy_parallel(iterate: object, index: int, seen: list[bool]) -> Iterator[None]:
    """numba_backend.nk.iterate replaced for the block by a wrapper recording its ``parallel`` argument."""
    def spy(*args: object) -> int:
        seen.append(bool(args[index]))
        return iterate(*args)

    numba_backend.nk.iterate = spy
    try:
        yield
    finally:
        numba_backend.nk.iterate = iterate


def test_parallel_min_pixels_selects_the_parallel_kernels_for_an_estimator() -> None:
    """FlowConfig.parallel_min_pixels binds the threshold to the estimator's backend (not a module global):
    with it at 1 every level runs the parallel solver and linearisation, and the flow is the same bit for bit
    as with the defaults (every level of this small pair serial); a config change selects the backend again.
    (The grey-value data term: the census term's form kernel is not the linearisation.)"""
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("one core: no parallel kernels")
    t = texture(60, 80, seed=2).image
    t1 = np.roll(t, 1, axis=1)
    cfg = FlowConfig.preset("stream_fast").replace(backend="numba", threads=2, levels=3, photometric="normalise")
    est = FlowEstimator(cfg)
    default = est.estimate(t, t1)
    assert select_backend("numba", 2).solve is solve_numba
    bound = select_backend("numba", 2, parallel_min_pixels=1)
    assert bound.solve.keywords == {"min_pixels": 1} and bound.linearise.keywords == {"min_pixels": 1}
    est.config = cfg.replace(parallel_min_pixels=1)  # re-selects the backend
    iterate, seen = numba_backend.nk.iterate, []
    with _spy_parallel(iterate, list(inspect.signature(iterate.py_func).parameters).index("parallel"), seen):
        parallel = est.estimate(t, t1)
    assert seen and all(seen)
    np.testing.assert_array_equal(parallel.flow, default.flow)
    assert parallel.stats.iterations == default.stats.iterations


def test_non_contiguous_and_float64_state_is_accepted() -> None:
    prob, st0 = random_case("l1_tv", False, seed=5)
    params = SolveParams(MODEL_SPECS["l1_tv"], 0.05, 0.3, "isotropic", 10, 0.0)
    ref = copy_state(st0)
    solve_numpy(prob, ref, params)
    odd = copy_state(st0)
    odd.v = np.asfortranarray(odd.v.astype(np.float64))
    solve_numba(Problem(prob.a[:, :, :], prob.c.astype(np.float64)), odd, params)
    assert odd.v.dtype == np.float32 and odd.v.flags.c_contiguous
    np.testing.assert_allclose(odd.v, ref.v, rtol=0, atol=AGREE)


def test_buffers_are_reused_for_the_same_shape() -> None:
    v = np.zeros((2, 17, 23), np.float32)
    first = numba_backend.work_buffers(v, None)
    again = numba_backend.work_buffers(v.copy(), None)  # the zero rows are new views of the same memory
    assert all(x.ctypes.data == y.ctypes.data and x.shape == y.shape for x, y in zip(first, again, strict=True))
    other = numba_backend.work_buffers(np.zeros((2, 18, 23), np.float32), None)
    assert other[0] is not first[0] and other[0].shape == (2, 18, 23)


def test_threads_get_their_own_kernel_buffers() -> None:
    """Two flows computed at once in two threads (two nodes in one process) must not share the solver's
    extrapolated variables or the kernels' row scratch: the kernels index the latter by numba's thread id,
    which starts at 0 in every calling thread's team."""
    v = np.zeros((2, 17, 23), np.float32)
    mine = (*numba_backend.work_buffers(v, None), *numba_backend.row_scratch(23))
    theirs: list[tuple[np.ndarray, ...]] = []
    t = threading.Thread(target=lambda: theirs.append(
        (*numba_backend.work_buffers(v, None), *numba_backend.row_scratch(23))))
    t.start()
    t.join()
    assert not any(np.shares_memory(a, b) for a, b in zip(mine, theirs[0], strict=True) if a.size > 4)
    assert not np.any(mine[3]) and not np.any(theirs[0][3])  # the zero Bregman row


@pytest.mark.parametrize("model", ["l1_tv", "l2_tv", "l1_tv_tv"])
def test_end_to_end_flow_agrees(model: str) -> None:
    """Whole coarse-to-fine pipeline (pyramid, warps, median, Bregman) on a small pair, both backends.

    Median filters and re-linearisation can amplify float32 round-off at a few pixels, so the bound is on
    the mean (~round-off) and, loosely, on the maximum."""
    t = texture(48, 64, seed=2)
    i0, i1 = pair_from_flow(t, constant_flow(48, 64, 1.3, -0.6) + rotation_flow(48, 64, 2.0))
    alpha = 0.002 if model == "l2_tv" else 0.025
    base = dict(model=model, alpha=alpha, levels=3, warps=3, iterations=30, median_filter=3,
                bregman_iterations=1)
    ref = FlowEstimator(FlowConfig(backend="numpy", **base)).estimate(i0, i1)
    fast = FlowEstimator(FlowConfig(backend="numba", **base)).estimate(i0, i1)
    assert (ref.backend, fast.backend) == ("numpy", "numba")
    assert np.abs(ref.flow).max() > 1.0
    diff = np.abs(fast.flow - ref.flow)
    assert diff.mean() < 1e-5 and diff.max() < 1e-3
    assert fast.stats.iterations == ref.stats.iterations


@pytest.mark.parametrize("preset", ["realtime", "fastest"])
def test_fast_presets_agree_with_the_numpy_reference(preset: str) -> None:
    """The fast presets end to end -- photometric stage, pyramid, B-spline source, the numba linearisation
    (interior blocks and mirrored border taps), 3-16 iterations per warp, 5x5 medians -- on an exactly
    rendered pair: the numba backend's flow is the numpy reference's to float32 round-off, and accurate."""
    h, w = 96, 128
    gt = constant_flow(h, w, 1.3, -0.6) + rotation_flow(h, w, 2.0)
    i0, i1 = pair_from_flow(texture(h, w, seed=4), gt)
    cfg = FlowConfig.preset(preset)
    ref = FlowEstimator(cfg.replace(backend="numpy")).estimate(i0, i1)
    fast = FlowEstimator(cfg.replace(backend="numba")).estimate(i0, i1)
    assert (ref.backend, fast.backend) == ("numpy", "numba")
    assert fast.stats.iterations == ref.stats.iterations and sum(fast.stats.iterations) > 0
    diff = np.abs(fast.flow - ref.flow)
    assert diff.mean() < 1e-5 and diff.max() < 1e-3
    assert aee(interior(fast.flow), interior(gt)) < 0.1  # zero flow: ~1.9


def test_each_estimator_runs_its_kernels_on_its_own_threads(monkeypatch: pytest.MonkeyPatch) -> None:
    """``threads`` belongs to the estimator, not the process: with FlowEstimator(threads=1) made before
    FlowEstimator(threads=2), each still solves on its own count (the solver kernel sees it as numba's thread
    count and as its serial / parallel choice), in one thread one after the other and concurrently in two;
    the caller's numba count is left as it was. (Once a module global that the last estimator set.)"""
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("one core: numba cannot run two threads")
    iterate, seen = numba_backend.nk.iterate, []
    parallel = list(inspect.signature(iterate.py_func).parameters).index("parallel")

    def spy(*args: object) -> int:
        seen.append((threading.current_thread().name, numba.get_num_threads(), args[parallel]))
        return iterate(*args)

    monkeypatch.setattr(numba_backend.nk, "iterate", spy)
    monkeypatch.setattr(numba_backend, "PARALLEL_MIN_PIXELS", 0)  # this test's small level runs in parallel too
    t = texture(40, 48, seed=1).image
    cfg = FlowConfig(backend="numba", levels=1, warps=1, iterations=5)
    estimators = {1: FlowEstimator(cfg.replace(threads=1)), 2: FlowEstimator(cfg.replace(threads=2))}
    before = numba.get_num_threads()
    for n in (1, 2, 1):
        seen.clear()
        estimators[n].estimate(t, t)
        assert {s[1:] for s in seen} == {(n, n > 1)}
        assert numba.get_num_threads() == before
    seen.clear()
    start = threading.Barrier(2)

    def work(n: int) -> None:
        start.wait()
        for _ in range(5):
            estimators[n].estimate(t, t)

    workers = [threading.Thread(target=work, args=(n,), name=f"threads={n}") for n in (1, 2)]
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    assert [{s[1] for s in seen if s[0] == w.name} for w in workers] == [{1}, {2}]
    assert numba_backend.resolve_threads(0) == numba_backend.resolve_threads(10_000) == numba.config.NUMBA_NUM_THREADS


class _Records(logging.Handler):
    """Collects the records that reach it."""

    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


@contextlib.contextmanager
def flow_node_log(level: int) -> Iterator[list[logging.LogRecord]]:
    """The records of the ``flow_node`` logger at ``level`` and above, taken at that logger itself.

    Not pytest's caplog: caplog listens on the root logger, and once ``launch`` is imported (colcon test
    loads launch_testing's pytest plugin in every ROS install) loggers created afterwards are LaunchLoggers
    that do not propagate, so caplog would see nothing although the backend logged.
    """
    logger = logging.getLogger("flow_node")
    handler, old = _Records(), logger.level
    logger.addHandler(handler)
    logger.setLevel(level)
    try:
        yield handler.records
    finally:
        logger.removeHandler(handler)
        logger.setLevel(old)


NUMPY_FIELDS = ("numpy", solve_numpy, NUMPY_WARPER, linearise, census_reliability, fuse, forward_backward_consistent,
                level_signature, census_form, confidence, 1, NUMPY.on_threads, splat_forward,
                confidence_at, sorted_sample, image_gradient, push_pull, level_planes, equalised,
                median_contrast, noise_sigma, edge_weight, weighted_median)
NUMBA_FIELDS = ("numba", solve_numba, WARPER, linearise_numba, census_reliability_numba, fuse_numba, consistent_numba,
                level_signature_numba, census_form_numba, confidence_numba,
                numba.config.NUMBA_NUM_THREADS, numba_backend.thread_count, splat_numba,
                confidence_at_numba, sorted_sample_numba, image_gradient_numba, push_pull_numba,
                planes_numba, ranks_numba, median_contrast_numba, noise_sigma_numba, edge_weight_numba,
                weighted_median_numba)


def test_backend_selection_and_log() -> None:
    with flow_node_log(logging.INFO) as records:
        assert select_backend("numpy") == NUMPY_FIELDS
        assert select_backend("auto").resolved() == NUMBA_FIELDS
        assert select_backend("numba").resolved() == NUMBA_FIELDS
    lines = [r.getMessage() for r in records]
    assert len(lines) == 3
    assert lines[0].startswith("flow_node backend: numpy")
    assert lines[1].startswith("flow_node backend: numba") and lines[2].startswith("flow_node backend: numba")


def test_fallback_when_numba_is_missing(monkeypatch: pytest.MonkeyPatch) -> None:
    """With the numba backend unimportable, auto degrades to numpy (with a warning), numba is an error."""
    import flow_node.core as core

    monkeypatch.setitem(sys.modules, "flow_node.core.numba_backend", None)  # import now raises ImportError
    monkeypatch.delattr(core, "numba_backend")
    with flow_node_log(logging.WARNING) as records:
        assert select_backend("auto") == NUMPY_FIELDS
    assert [r.levelno for r in records] == [logging.WARNING]
    assert "numba not importable" in records[0].getMessage()
    with pytest.raises(ConfigError, match="numba"):
        select_backend("numba")
    assert FlowEstimator(FlowConfig(backend="auto")).backend == "numpy"


def test_solver_runs_the_kernel_of_its_data_term(monkeypatch: pytest.MonkeyPatch) -> None:
    """The iteration kernels are compiled per data term (numba_kernels.ITERATE_NAMES; the pixel loop carries
    that term's code only): solve_numba picks the plain one for rho = a . v + c and the quadratic one for a
    census form, and nothing else."""
    assert [numba_backend.nk.data_code(q, m, bc) for q, m, bc in
            ((False, False, False), (True, False, False), (False, True, False), (False, True, True))] == [0, 1, 2, 3]
    seen: list[str] = []
    for name in numba_backend.nk.ITERATE_NAMES:
        kernel = getattr(numba_backend.nk, name)
        monkeypatch.setattr(numba_backend.nk, name,
                            lambda *args, _k=kernel, _n=name: seen.append(_n) or _k(*args))
    prob, st0 = random_case("l1_tv", False, seed=4)
    params = SolveParams(MODEL_SPECS["l1_tv"], 0.05, 0.3, "isotropic", 5, 0.0)
    solve_numba(prob, copy_state(st0), params)
    q = np.zeros((5, H, W), np.float32)
    q[0] = q[2] = 1.0  # an identity form: T = I, g = 0
    solve_numba(Problem(prob.a, prob.c, q=q), copy_state(st0), params)
    assert seen == ["iterate", "iterate_quad"]
