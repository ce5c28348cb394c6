"""Cold start (issue 29): a fresh process loads every numba kernel from the on-disk cache instead of compiling
it again, and importing the engine sets no process-wide state (flow_node/process.py).

The cache test runs the engine in two fresh interpreters with the tests' NUMBA_CACHE_DIR (the environment
is inherited): the first fills the cache for every path a preset takes on a 40 px pan (initialisation,
fusion and its forward-backward check, refinement, reliability; then the confidence), the second must
then find every kernel it uses there -- numba's own per-dispatcher statistics, a miss being a compilation. A
kernel built so that numba cannot key it stably (a closure over another dispatcher, an uncached ``@njit``, a
type that differs per process) shows up here as a miss, with its name. FlowEstimator.warmup (the node's
start-up) must reach the fusion's and the confidence's kernels as well.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

import flow_node
from flow_node.bag import dask_worker
from flow_node.core import FlowConfig, FlowEstimator, numba_confidence, numba_fusion

# One process: every preset on a 240x180 pan moving (40, 12) px -- DIS initialises, the fusion runs on
# two levels -- then numba's statistics of every flow_node dispatcher alive, as JSON.
CHILD = """
import gc, json
import numpy as np
from numba.core.dispatcher import Dispatcher
from flow_node.bag.scenes import AffineMotion, Layer, Scene, Texture
from flow_node.core import FlowConfig, FlowEstimator, PRESETS

pan = Layer(Texture.random(np.random.default_rng(4), fmin=1 / 100), AffineMotion((119.5, 89.5), (40.0, 12.0)))
scene = Scene("pan", (240, 180), (pan,))
i0, i1 = ((scene.render(t) @ np.array([0.299, 0.587, 0.114])).astype(np.float32) for t in (0, 1))
inits = [FlowEstimator(FlowConfig.preset(p).replace(backend="numba")).estimate_grey(i0, i1).stats.init
         for p in PRESETS]
FlowEstimator(FlowConfig(backend="numba")).confidence(i0, i1, np.zeros(i0.shape + (2,), np.float32))
stats = {}
for d in gc.get_objects():
    if isinstance(d, Dispatcher) and d.py_func.__module__.startswith("flow_node"):
        name = d.py_func.__module__ + "." + d.py_func.__qualname__
        stats[name] = [sum(d.stats.cache_hits.values()), sum(d.stats.cache_misses.values())]
print(json.dumps({"inits": inits, "stats": stats}))
"""


# One process: each preset (and census) solves the same textured pan twice; the largest difference of the
# first flow from the second (px), as JSON.
REPEAT = """
import json
import numpy as np
from flow_node.bag.scenes import AffineMotion, Layer, Scene, Texture
from flow_node.core import FlowConfig, FlowEstimator

pan = Layer(Texture.random(np.random.default_rng(7), fmin=1 / 60),
            AffineMotion((159.5, 119.5), (3.3, -1.7), theta=0.01))
scene = Scene("pan", (320, 240), (pan,))
i0, i1 = ((scene.render(t) @ np.array([0.299, 0.587, 0.114])).astype(np.float32) for t in (0, 1))
diffs = {}
for name, cfg in (("fastest", FlowConfig.preset("fastest")), ("realtime", FlowConfig.preset("realtime")),
                  ("census", FlowConfig.preset("fastest").replace(photometric="census"))):
    est = FlowEstimator(cfg.replace(backend="numba"))
    first, second = (est.estimate_grey(i0, i1).flow for _ in range(2))
    diffs[name] = float(np.abs(first - second).max())
print(json.dumps(diffs))
"""


def run_child(code: str = CHILD) -> dict[str, Any]:
    """Run ``code`` (:data:`CHILD`) in a fresh interpreter on this checkout's flow_node; its JSON."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(flow_node.__file__).parents[1]),
                                                        os.environ.get("PYTHONPATH", "")])}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_fresh_process_compiles_no_kernel() -> None:
    run_child()  # fills the cache (compiles on a cold one)
    second = run_child()
    assert all(second["inits"]), second["inits"]  # every preset took the initialisation and fusion path
    used = {name: hm for name, hm in second["stats"].items() if sum(hm)}
    for kernel in ("iterate", "linearise_kernel", "bspline_columns", "unexplained_kernel", "residual_kernel",
                   "choose_kernel", "settle_kernel", "consistent_kernel", "planes_kernel", "terms_kernel",
                   "confidence_kernel", "radix_sort_kernel"):
        assert any(name.endswith("." + kernel) for name in used), (kernel, sorted(used))
    compiled = {name: misses for name, (_, misses) in used.items() if misses}
    assert not compiled, f"compiled again in a fresh process (not cached): {compiled}"


def test_a_process_first_solve_equals_its_later_ones() -> None:
    """The numba kernels' result depends on their input alone: the first solve of a fresh process equals the
    next solve of the same pair bit for bit (with the solver kernels on full fastmath it did not:
    numba_kernels.FASTMATH)."""
    diffs = run_child(REPEAT)
    assert diffs == {"fastest": 0.0, "realtime": 0.0, "census": 0.0}, diffs


# One process: a realtime solve of a small pan with the numba backend, then which kernel modules it imported,
# then the same after a confidence, as JSON.
DEFERRED = """
import json, sys
import numpy as np
from flow_node.core import FlowConfig, FlowEstimator
rng = np.random.default_rng(3)
i0 = rng.random((60, 80), dtype=np.float32)
est = FlowEstimator(FlowConfig.preset("realtime").replace(backend="numba"))
est.estimate_grey(i0, np.roll(i0, 2, axis=1))
kernels = lambda: sorted(m for m in sys.modules if m.startswith("flow_node.core.numba_"))
solved = kernels()
est.confidence(i0, i0, np.zeros(i0.shape + (2,), np.float32))
print(json.dumps({"solved": solved, "confidence": kernels()}))
"""


def test_a_solve_imports_only_the_kernels_it_runs() -> None:
    """The census, confidence and stream kernels' modules are imported when first called (backends.Deferred),
    not by selecting the numba backend: a fresh process's first flow does not create their dispatchers."""
    out = run_child(DEFERRED)
    assert not {"flow_node.core.numba_census", "flow_node.core.numba_confidence",
                "flow_node.core.numba_temporal"} & set(out["solved"]), out["solved"]
    assert "flow_node.core.numba_kernels" in out["solved"]
    assert "flow_node.core.numba_confidence" in out["confidence"]


def test_importing_the_engine_sets_no_process_state() -> None:
    """Importing the numba kernels leaves OMP_WAIT_POLICY alone: only an executable's main() sets it."""
    env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    env["PYTHONPATH"] = str(Path(flow_node.__file__).parents[1])
    code = ("import os; import flow_node.core.numba_backend, flow_node.core.numba_fusion; "
            "print(os.environ.get('OMP_WAIT_POLICY'))")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "None"


def test_the_dask_workers_preload_lets_idle_threads_sleep(monkeypatch: pytest.MonkeyPatch) -> None:
    """A worker process of a Dask cluster runs no executable's main(): its preload applies the setting
    (the executables' main() are checked in test_node.py)."""
    monkeypatch.delenv("OMP_WAIT_POLICY", raising=False)
    monkeypatch.setattr(dask_worker, "keep_freed_memory", lambda: True)
    dask_worker.dask_setup(None)
    assert os.environ["OMP_WAIT_POLICY"] == "passive"


def test_warmup_runs_every_fusion_kernel(monkeypatch: pytest.MonkeyPatch) -> None:
    """FlowEstimator.warmup (the node's start-up, flow_bag eval's first bag) reaches the fusion's kernels
    too, which its small solve does not, and the confidence's: the first frame that moves far (or the
    first subscriber of ~/confidence or a derived output) then neither compiles them (a new install) nor
    reads them from the cache."""
    called: set[str] = set()

    def counting(module: Any, name: str) -> Callable[..., Any]:
        kernel = getattr(module, name)

        def run(*args: Any) -> Any:
            called.add(name)
            return kernel(*args)

        return run

    kernels = {numba_fusion: ("residual_kernel", "choose_kernel", "settle_kernel", "consistent_kernel"),
               numba_confidence: ("planes_kernel", "terms_kernel", "confidence_kernel", "confidence_at_kernel",
                                  "ratio_at_kernel")}
    for module, names in kernels.items():
        for name in names:
            monkeypatch.setattr(module, name, counting(module, name))
    FlowEstimator(FlowConfig.preset("fastest").replace(backend="numba")).warmup()
    assert called == {name for names in kernels.values() for name in names}
