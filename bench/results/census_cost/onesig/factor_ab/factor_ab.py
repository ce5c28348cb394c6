"""One-off (round onesig): numba_census.factor_numba's and census_form_numba's (a warp's form, bspline, L1) CPU
time per call on a 640x480 level, one thread, in one process: main's module (a worktree of main at
/work/wt-onesig-base), this tree's, and variants (copies of this tree's numba_census.py with one line changed, given
as paths), interleaved, N blocks of 50 calls, medians (us).

    PYTHONPATH=$PWD NUMBA_CACHE_DIR=/tmp/cache python bench/results/census_cost/onesig/factor_ab/factor_ab.py 8 [path]
"""

import importlib.util
import json
import statistics as st
import sys
import time
from types import ModuleType

import numba
import numpy as np

from flow_node.core import numba_backend, numba_census
from flow_node.core.census import CENSUS

MAIN = "/work/wt-onesig-base/flow_node/core/numba_census.py"


def load(name: str, path: str) -> ModuleType:
    """The module at ``path`` as flow_node.core.``name`` (its relative imports resolve in flow_node.core)."""
    spec = importlib.util.spec_from_file_location(f"flow_node.core.{name}", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


def main() -> None:
    numba.set_num_threads(1)
    mods = {"main": load("nc_main", MAIN), "onesig": numba_census,
            **{v: load(f"nc_v{i}", v) for i, v in enumerate(sys.argv[2:])}}
    rng = np.random.default_rng(0)
    img = rng.random((480, 640), dtype=np.float32) * 0.3 + np.sin(np.arange(640, dtype=np.float32) / 7)[None] * 0.3
    out = np.empty_like(img)
    img1 = np.roll(img, 3, axis=1)
    coefs = numba_backend.WARPER.coefficients(img1[None], "bspline")
    v0 = np.full((2, 480, 640), 0.4, np.float32)
    fns = {f"factor {k}": (lambda m=m: m.factor_numba(img, CENSUS, out=out)) for k, m in mods.items()}
    levels = {k: m.level_signature_numba(img, CENSUS)[0].copy() for k, m in mods.items()}
    fns.update({f"form {k}": (lambda m=m, k=k: m.census_form_numba(levels[k], None, coefs, img1[None], v0, "bspline",
                                                                   True, CENSUS)) for k, m in mods.items()})
    res: dict[str, list[float]] = {k: [] for k in fns}
    for f in fns.values():
        f()
    for _ in range(int(sys.argv[1])):
        for k, f in fns.items():
            ts = []
            for _ in range(50):
                t = time.process_time_ns()
                f()
                ts.append(time.process_time_ns() - t)
            res[k].append(st.median(ts) / 1e3)
    print(json.dumps({k: round(st.median(v), 1) for k, v in res.items()}))


if __name__ == "__main__":
    main()
