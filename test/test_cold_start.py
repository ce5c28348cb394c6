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
from flow_node import numba_patch
from flow_node.bag import dask_worker
from flow_node.core import FlowConfig, FlowEstimator, numba_census, numba_confidence, numba_fusion, numba_sort

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


def run_child(code: str = CHILD, env_extra: dict[str, str] | None = None) -> dict[str, Any]:
    """Run ``code`` (:data:`CHILD`) in a fresh interpreter on this checkout's flow_node (``env_extra`` added to
    the environment); its JSON."""
    path = os.pathsep.join([str(Path(flow_node.__file__).parents[1]), os.environ.get("PYTHONPATH", "")])
    env = {**os.environ, **(env_extra or {}), "PYTHONPATH": path}
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
                   "confidence_kernel", "radix_sort_kernel", "gradient_kernel"):
        assert any(name.endswith("." + kernel) for name in used), (kernel, sorted(used))
    compiled = {name: misses for name, (_, misses) in used.items() if misses}
    assert not compiled, f"compiled again in a fresh process (not cached): {compiled}"


def test_a_process_first_solve_equals_its_later_ones() -> None:
    """The numba kernels' result depends on their input alone: the first solve of a fresh process equals the
    next solve of the same pair bit for bit (with the solver kernels on full fastmath it did not:
    numba_kernels.FASTMATH)."""
    diffs = run_child(REPEAT)
    assert diffs == {"fastest": 0.0, "realtime": 0.0, "census": 0.0}, diffs


# One process: the census term's quadratic form (numba_census.census_form_numba) of one warp of a 120 x 160 pair
# and frame 1's signature planes (numba_census.census_planes_numba, the fusion's), as JSON (their bytes as hex).
CENSUS_FORM = """
import json
import numpy as np
from flow_node.core import numba_census
from flow_node.core.census import CENSUS
h, w = 120, 160
y, x = np.mgrid[0:h, 0:w].astype(np.float32)
noise = np.random.default_rng(5).standard_normal((h, w)).astype(np.float32)
def frame(shift):
    return (0.5 + 0.2 * np.sin((x + shift) / 5.3) * np.cos(y / 4.1) + 0.1 * np.sin((x + shift + y) / 2.7)
            + 0.02 * noise).astype(np.float32)[None]
f0, _ = numba_census.level_signature_numba(frame(0.0), CENSUS)
v0 = np.zeros((2, h, w), np.float32)
v0[0] = 0.6 + 0.1 * np.sin(y / 9)
form = numba_census.census_form_numba(f0, None, frame(0.7), frame(0.7), v0, "keys", True, CENSUS)
planes = numba_census.census_planes_numba(frame(0.7)[0], CENSUS)
print(json.dumps([form.tobytes().hex(), planes.tobytes().hex()]))
"""


# One process: the 3-D engine's flow (volume.estimate_volume, `realtime`, numba) between two 16 x 24 x 32 volumes,
# as JSON (the flow's bytes as hex).
VOLUME_FLOW = """
import json
import numpy as np
from flow_node.core import FlowConfig
from flow_node.core.volume import estimate_volume
z, y, x = np.mgrid[0:16, 0:24, 0:32].astype(np.float32)
def vol(s):
    return (0.5 + 0.2 * np.sin((x + s) / 3.1) * np.cos(y / 2.7) + 0.15 * np.sin((z + 0.5 * s) / 2.3 + x / 4.0)
            ).astype(np.float32)
flow = estimate_volume(vol(0.0), vol(0.8), FlowConfig.preset("realtime").replace(backend="numba")).flow
print(json.dumps(flow.tobytes().hex()))
"""


@pytest.mark.parametrize("code", [CENSUS_FORM, VOLUME_FLOW], ids=["census_form", "volume_flow"])
def test_kernels_compute_the_same_compiled_or_cached(tmp_path: Path, code: str) -> None:
    """A kernel computes the same bits in the process that compiles it (a new install's first process) as in a
    later one that reads it from numba's cache. With fastmath=True (reassoc, arcp) they did not: 28,958 of the
    census form's 96,000 values differed by up to 3e-8, and `realtime` census flows by 2e-3 px
    (numba_signature.JIT); the 3-D engine's flows differed for all five models (numba_volume._JIT). The 2-D
    grey-value paths (warp and confidence kernels, fastmath=True) were checked alike once, every preset, small and
    large motion: equal (docs/engine.md, "Compiled kernels")."""
    cache = {"NUMBA_CACHE_DIR": str(tmp_path / "numba_cache")}  # empty: the first child compiles
    compiled = run_child(code, cache)
    cached = run_child(code, cache)
    assert compiled == cached


# One process: `quality` twice on a 584x388 pan (small motion), the CPU time spent in the solver kernel
# (numba_kernels.iterate, the grey-value data term's solver: quality's own term is census) by each flow, as JSON.
FIRST_SOLVE = """
import json, time
import numpy as np
from flow_node.bag.scenes import AffineMotion, Layer, Scene, Texture
from flow_node.core import FlowConfig, FlowEstimator, numba_kernels
spent, kernel = [], numba_kernels.iterate
def timed(*args):
    start = time.process_time()
    out = kernel(*args)
    spent[-1] += time.process_time() - start
    return out
numba_kernels.iterate = timed
pan = Layer(Texture.random(np.random.default_rng(7), fmin=1 / 60),
            AffineMotion((291.5, 193.5), (3.3, -1.7), theta=0.01))
scene = Scene("pan", (584, 388), (pan,))
i0, i1 = ((scene.render(t) @ np.array([0.299, 0.587, 0.114])).astype(np.float32) for t in (0, 1))
est = FlowEstimator(FlowConfig.preset("quality").replace(backend="numba", photometric="normalise"))
for _ in range(2):
    spent.append(0.0)
    est.estimate_grey(i0, i1)
print(json.dumps(spent))
"""


def test_a_process_first_solve_runs_as_fast_as_its_later_ones() -> None:
    """The solver kernel's CPU time in a fresh process's first flow is about that of its second (the first also
    reads the kernel from the cache, ~20 ms; the child's second run, so nothing is compiled). Before the
    kernels' loads were kept inside their arrays (numba_kernels.py), masked loads past the data term's end,
    on the fresh heap's untouched pages, made it 3.8x the second's here (docs/engine.md, "Compiled
    kernels")."""
    run_child(FIRST_SOLVE)  # fills the cache
    first, second = run_child(FIRST_SOLVE)
    assert first < 1.5 * second, (first, second)


# One process: a realtime solve of a small pan with the numba backend, then which kernel modules it imported,
# then the same after a confidence, as JSON.
DEFERRED = """
import json, sys
import numpy as np
from flow_node.core import FlowConfig, FlowEstimator
rng = np.random.default_rng(3)
i0 = rng.random((60, 80), dtype=np.float32)
est = FlowEstimator(FlowConfig.preset("realtime").replace(backend="numba", photometric="normalise"))
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
    assert {"flow_node.core.numba_kernels", "flow_node.core.numba_judge"} <= set(out["solved"])  # every solve's
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
    """A worker process of a Dask cluster runs no executable's main(): its preload applies the settings
    (the executables' main() are checked in test_node.py), numba's cached-kernel read among them."""
    monkeypatch.delenv("OMP_WAIT_POLICY", raising=False)
    monkeypatch.setattr(dask_worker, "keep_freed_memory", lambda: True)
    deferred: list[bool] = []
    monkeypatch.setattr(dask_worker, "defer_kernel_bitcode", lambda: deferred.append(True) or True)
    dask_worker.dask_setup(None)
    assert os.environ["OMP_WAIT_POLICY"] == "passive"
    assert deferred == [True]


@pytest.mark.parametrize("photometric", ["normalise", "census"])
def test_warmup_runs_every_fusion_kernel(monkeypatch: pytest.MonkeyPatch, photometric: str) -> None:
    """FlowEstimator.warmup (the node's start-up, flow_bag eval's first bag) reaches the fusion's kernels
    too, which its small solve does not, and the confidence's: the first frame that moves far (or the
    first subscriber of ~/confidence or a derived output) then neither compiles them (a new install) nor
    reads them from the cache. With the census data term also its cost planes and the initialisation's ranks."""
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
    if photometric == "census":  # the cost planes: the census term's factor kernel with its planes (numba_census)
        kernels = {**kernels, numba_census: ("census_planes_numba",), numba_sort: ("ranks_kernel",)}
    for module, names in kernels.items():
        for name in names:
            monkeypatch.setattr(module, name, counting(module, name))
    FlowEstimator(FlowConfig.preset("fastest").replace(backend="numba", photometric=photometric)).warmup()
    assert called == {name for names in kernels.values() for name in names}


# One process: the textured pan of CHILD moving far (initialisation, fusion) and a small motion, `realtime` and
# `fastest`; in MODE "patched" the executables' numba patch first (process.defer_kernel_bitcode). Prints
# the flows' SHA-256, flow_node's cache misses and how many kernel libraries were read with the bitcode
# deferred (still unparsed), as JSON.
PATCHED = """
import gc, hashlib, json
import numpy as np
from numba.core.codegen import CPUCodeLibrary
from numba.core.dispatcher import Dispatcher
from flow_node import numba_patch, process
applied = process.defer_kernel_bitcode() if MODE == "patched" else False
from flow_node.bag.scenes import AffineMotion, Layer, Scene, Texture
from flow_node.core import FlowConfig, FlowEstimator
flows = hashlib.sha256()
for shift in ((40.0, 12.0), (1.5, -0.5)):
    pan = Layer(Texture.random(np.random.default_rng(4), fmin=1 / 100), AffineMotion((119.5, 89.5), shift))
    scene = Scene("pan", (240, 180), (pan,))
    i0, i1 = ((scene.render(t) @ np.array([0.299, 0.587, 0.114])).astype(np.float32) for t in (0, 1))
    for preset in ("realtime", "fastest"):
        flows.update(FlowEstimator(FlowConfig.preset(preset).replace(backend="numba")).estimate_grey(i0, i1).flow)
objects = gc.get_objects()
misses = sum(sum(d.stats.cache_misses.values()) for d in objects
             if isinstance(d, Dispatcher) and d.py_func.__module__.startswith("flow_node"))
deferred = sum(isinstance(o, CPUCodeLibrary) and numba_patch.deferred(o) for o in objects)
print(json.dumps({"applied": applied, "flows": flows.hexdigest(), "misses": misses, "deferred": deferred}))
"""


@pytest.mark.skipif(numba_patch.installed_numba() is None, reason="numba is not installed")
def test_the_bitcode_patch_reads_the_same_kernels_and_flows() -> None:
    """process.defer_kernel_bitcode (numba_patch.py): with it a fresh process reads every kernel from the cache
    through the deferred path (none compiled, their bitcode left unparsed) and computes the same flows, bit for
    bit, as numba's own read; on a numba version it was not checked against it does not apply."""
    run_child(PATCHED.replace("MODE", "'stock'"))  # fills the cache
    stock, patched = (run_child(PATCHED.replace("MODE", repr(mode))) for mode in ("stock", "patched"))
    assert patched["applied"] == (numba_patch.installed_numba() in numba_patch.CHECKED)
    assert stock["misses"] == patched["misses"] == 0, (stock, patched)
    assert stock["flows"] == patched["flows"]
    assert stock["deferred"] == 0
    if patched["applied"]:
        assert patched["deferred"] >= 7, patched  # bspline, linearise, iterate and the fusion's four


@pytest.mark.skipif(numba_patch.installed_numba() not in numba_patch.CHECKED,
                    reason="the patch applies only to the numba versions it was checked against")
def test_the_patched_numba_functions_are_the_checked_ones() -> None:
    """The numba functions the patch replaces or relies on are, in the installed numba, the source it was
    written against (a numba upgrade that changed them must be checked and CHECKED / SOURCE_SHA256 updated)."""
    assert numba_patch.stock_source_digest() == numba_patch.SOURCE_SHA256


# One process, NUMBA_CACHE_DIR a fresh folder: a cached kernel read (patched) from the cache that an earlier
# run of the same code filled, then a new, uncached kernel that calls it -- numba links the first one's module
# into it, the one use of the deferred bitcode. Prints the results and whether the bitcode was deferred and
# then parsed, as JSON.
LINKED = """
import json, sys
sys.path.insert(0, sys.argv[1])
from flow_node import numba_patch, process
process.defer_kernel_bitcode()
import numba
from callee import scaled
first = scaled(3.0)
library = scaled.overloads[scaled.signatures[0]].library
deferred = numba_patch.deferred(library)
@numba.njit
def caller(x):
    return scaled(x) + 1.0
print(json.dumps({"first": first, "caller": caller(3.0), "deferred": deferred,
                  "parsed": not numba_patch.deferred(library), "hits": sum(scaled.stats.cache_hits.values())}))
"""


@pytest.mark.skipif(numba_patch.installed_numba() not in numba_patch.CHECKED,
                    reason="the patch applies only to the numba versions it was checked against")
def test_a_deferred_kernel_links_into_a_new_compilation(tmp_path: Path) -> None:
    """A kernel read with its bitcode deferred can still be linked into a later compilation that calls it:
    the bitcode is parsed then, and the caller computes what the kernel does."""
    (tmp_path / "callee.py").write_text("import numba\n\n\n@numba.njit(cache=True)\n"
                                        "def scaled(x):\n    return x * 2.5 + 1.0\n")
    code = LINKED.replace("sys.argv[1]", repr(str(tmp_path)))
    env_cache = {"NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    run_child(code, env_cache)  # compiles `scaled` into the cache
    out = run_child(code, env_cache)
    assert out == {"first": 8.5, "caller": 9.5, "deferred": True, "parsed": True, "hits": 1}, out


# One process: a large-motion `realtime` solve with numba's own read, which this wraps to compare, for every
# kernel read from the cache, the defined symbols numba takes from the parsed bitcode with those the patch
# takes from the object code. Prints the kernels read and those whose sets differ, as JSON.
SYMBOLS = """
import json
import numpy as np
from llvmlite import binding as ll
from numba.core import codegen
from flow_node import numba_patch
from flow_node.bag.scenes import AffineMotion, Layer, Scene, Texture
from flow_node.core import FlowConfig, FlowEstimator
stock, read, differ = codegen.CPUCodeLibrary._unserialize.__func__, [], []
def compare(cls, codegen_, state):
    name, kind, data = state
    module = ll.parse_bitcode(data[1])
    numba_names = {g.name for group in (module.functions, module.global_variables) for g in group
                   if not g.is_declaration}
    read.append(name)
    if numba_patch.elf_defined_symbols(data[0]) != numba_names:
        differ.append(name)
    return stock(cls, codegen_, state)
codegen.CPUCodeLibrary._unserialize = classmethod(compare)
pan = Layer(Texture.random(np.random.default_rng(4), fmin=1 / 100), AffineMotion((119.5, 89.5), (40.0, 12.0)))
scene = Scene("pan", (240, 180), (pan,))
i0, i1 = ((scene.render(t) @ np.array([0.299, 0.587, 0.114])).astype(np.float32) for t in (0, 1))
FlowEstimator(FlowConfig.preset("realtime").replace(backend="numba")).estimate_grey(i0, i1)
print(json.dumps({"read": read, "differ": differ}))
"""


@pytest.mark.skipif(sys.platform != "linux" or numba_patch.installed_numba() is None,
                    reason="numba's object code is ELF on Linux only")
def test_the_object_code_defines_the_symbols_numba_reads_from_the_bitcode() -> None:
    """numba_patch.elf_defined_symbols gives, for each of the engine's kernels, exactly the names numba's own
    read takes from the parsed bitcode (JitEngine._load_defined_symbols)."""
    run_child(SYMBOLS)  # fills the cache
    out = run_child(SYMBOLS)
    assert len(out["read"]) >= 7 and not out["differ"], out


# One process: numba's start-up and one cached kernel (the bench's "start" process), then, with MODE "skip",
# process.skip_final_collection; prints the CPU seconds spent so far. The parent takes the whole process's.
EXIT = """
import time
import numpy as np
from flow_node import process
from flow_node.core import numba_backend, numba_fusion
numba_backend.image_gradient_numba(np.zeros((4, 4), np.float32), "central")
if MODE == "skip":
    process.skip_final_collection()
print(time.process_time(), flush=True)
"""


def exit_cpu_seconds(mode: str) -> float:
    """CPU seconds a fresh process of :data:`EXIT` spends after its last statement: its exit."""
    env = {**os.environ, "PYTHONPATH": str(Path(flow_node.__file__).parents[1])}
    proc = subprocess.Popen([sys.executable, "-c", EXIT.replace("MODE", repr(mode))], env=env,
                            stdout=subprocess.PIPE, text=True)
    out = proc.stdout.read() if proc.stdout else ""
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    assert proc.returncode == 0
    return usage.ru_utime + usage.ru_stime - float(out)


def test_skipping_the_final_collection_shortens_the_exit() -> None:
    """process.skip_final_collection (flow_estimate's main() ends by it): with numba loaded, the interpreter's
    exit collects its object graph, ~0.1 s of CPU; frozen, the exit costs a fraction of that (CPU time, not
    wall time: the same on a busy machine)."""
    exit_cpu_seconds("stock")  # fills the kernel cache if empty
    stock = min(exit_cpu_seconds("stock") for _ in range(2))
    skip = min(exit_cpu_seconds("skip") for _ in range(2))
    assert skip < 0.5 * stock, (skip, stock)
