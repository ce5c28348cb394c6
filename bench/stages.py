"""Where a call's time goes: the engine's stages for some presets beside OpenCV DIS, one run, interleaved.

    PYTHONPATH=$PWD .venv-bench/bin/python bench/stages.py --out bench/results/stages.json
    PYTHONPATH=$PWD .venv-bench/bin/python bench/stages.py --base ../main   # + another checkout's engine

Per case (a preset on a pair) the stage functions the engine calls are wrapped with timers: grey
conversion, the photometric stage, the initialisation (the DIS gate run and, for a pair that moves far, its
backward run), the pyramid, the refinement (everything in ``refine_levels``), the fusion, the output layout
and the reliability figure; 'other' is what is left of the call (the driver's glue). Per round every
method runs once, the order rotating (DIS ultrafast, DIS medium on the 8-bit frames the suite hands them,
and each preset); per stage the median over the rounds. Ratios are to DIS ultrafast / DIS medium in the same
rounds. With ``--base DIR`` the engine of another checkout (DIR/flow_node/core, imported under another
package name, ``flow_node_base``) runs in the same rounds as ``base:<preset>``, so before/after ratios come
from one interleaved run; names that engine lacks are skipped.

Pairs: an exactly rendered fine-texture pair (the suite's tune seed 0) at 320x240 and 640x480, and the
KITTI pairs of ../shared/data/large (1242x375; 000045 moves ~11 px, 000000 ~52 px: the second is where
realtime fuses its DIS initialisation).
"""

from __future__ import annotations

import argparse
import hashlib
import importlib
import json
import shutil
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # bench.* when run as a file

from flow_node.core import api, engine  # noqa: E402
from flow_node.core.api import FlowEstimator  # noqa: E402
from flow_node.core.config import FlowConfig  # noqa: E402
from flow_node.core.flowio import read_image  # noqa: E402
from flow_node.core.initialise import to_u8  # noqa: E402

# (module, function name, stage label)
WRAPPED = ((api, "to_grey", "grey"), (engine, "stage", "photometric"), (engine, "initialise", "initialise"),
           (engine, "make_pyramid", "pyramid"), (engine, "refine_levels", "refine"),
           (engine, "fuse_on_level", "fusion"), (engine, "candidates_on_level", "fusion"),
           (engine, "interleaved_flow", "layout"),
           (api, "ensure_finite", "finite"))
LARGE = Path(__file__).resolve().parent.parent.parent / "shared" / "data" / "large"


class Timers:
    """Accumulates seconds per stage label while ``active``; nested wrapped calls count in their outer one
    only (refine_levels calls nothing wrapped)."""

    def __init__(self) -> None:
        self.acc: dict[str, float] = defaultdict(float)
        self.depth = 0

    def wrap(self, fn: Any, label: str) -> Any:
        def timed(*args: Any, **kwargs: Any) -> Any:
            if self.depth:
                return fn(*args, **kwargs)
            self.depth += 1
            start = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                self.acc[label] += time.perf_counter() - start
                self.depth -= 1
        return timed


def install(timers: Timers, api_module: Any = api, engine_module: Any = engine) -> None:
    modules = {api: api_module, engine: engine_module}
    for module, name, label in WRAPPED:
        target = modules[module]
        if hasattr(target, name):
            setattr(target, name, timers.wrap(getattr(target, name), label))


def load_base(checkout: str) -> tuple[Any, Any, Any]:
    """(api, engine, config) modules of ``checkout``'s engine, imported as package ``flow_node_base`` from a
    copy at a fixed path per checkout (numba caches compiled kernels by source path; freshly compiled
    kernels differ from cached ones by ~1e-4 px in the flow, so a comparison must load both sides alike)."""
    tag = hashlib.sha1(str(Path(checkout).resolve()).encode()).hexdigest()[:10]
    root = Path(tempfile.gettempdir()) / f"stages_base_{tag}"
    shutil.rmtree(root / "flow_node_base", ignore_errors=True)
    shutil.copytree(Path(checkout) / "flow_node" / "core", root / "flow_node_base" / "core",
                    ignore=shutil.ignore_patterns("__pycache__"))
    (root / "flow_node_base" / "__init__.py").write_text("")
    sys.path.insert(0, str(root))
    return tuple(importlib.import_module(f"flow_node_base.core.{m}") for m in ("api", "engine", "config"))


def fine_pair(size: tuple[int, int]) -> tuple[str, np.ndarray, np.ndarray]:
    from bench.suite.synthetic import fine

    sample = next(iter(fine("tune", True, size)))
    return f"fine_{size[0]}x{size[1]}", sample.f0, sample.f1


def large_pair(name: str) -> tuple[str, np.ndarray, np.ndarray]:
    d = LARGE / name
    return name, read_image(d / "frame0.png"), read_image(d / "frame1.png")


def run_case(label: str, f0: np.ndarray, f1: np.ndarray, presets: list[str], rounds: int,
             timers: Timers, base: tuple[Any, Any, Any] | None = None) -> dict[str, Any]:
    g0, g1 = api.to_grey(f0), api.to_grey(f1)
    u0, u1 = to_u8(g0), to_u8(g1)
    dis = {"dis_ultrafast": cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST),
           "dis_medium": cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)}
    estimators = {p: FlowEstimator(FlowConfig.preset(p)) for p in presets}
    if base is not None:
        estimators.update({f"base:{p}": base[0].FlowEstimator(base[2].FlowConfig.preset(p)) for p in presets})
        presets = presets + [f"base:{p}" for p in presets]
    for est in estimators.values():
        est.warmup()
        est.estimate(f0, f1)
    rel = {p: est._backend.reliability for p, est in estimators.items()}
    for p, est in estimators.items():
        est._backend = est._backend._replace(reliability=timers.wrap(rel[p], "reliability"))
    names = list(dis) + presets
    samples: dict[str, list[dict[str, float]]] = {n: [] for n in names}
    for r in range(rounds):
        k = r % len(names)
        for n in names[k:] + names[:k]:
            timers.acc.clear()
            start = time.perf_counter()
            if n in dis:
                dis[n].calc(u0, u1, None)
            else:
                estimators[n].estimate(f0, f1)
            total = time.perf_counter() - start
            row = dict(timers.acc)
            row["total"] = total
            row["other"] = total - sum(timers.acc.values())
            row["fixed"] = total - timers.acc.get("refine", 0.0)
            samples[n].append(row)
    med = {n: {k: float(np.median([s.get(k, 0.0) for s in rows])) for k in rows[0]} for n, rows in samples.items()}
    uf, md = med["dis_ultrafast"]["total"], med["dis_medium"]["total"]
    out = {"size": [int(f0.shape[1]), int(f0.shape[0])], "rounds": rounds, "ms": {n: {k: 1e3 * v for k, v in m.items()}
                                                                                   for n, m in med.items()},
           "x_dis_ultrafast": {p: {k: v / uf for k, v in med[p].items()} for p in presets},
           "x_dis_medium": {p: {k: v / md for k, v in med[p].items()} for p in presets}}
    print(f"{label} {f0.shape[1]}x{f0.shape[0]}: DIS ultrafast {1e3 * uf:.2f} ms, medium {1e3 * md:.2f} ms", flush=True)
    for p in presets:
        parts = ", ".join(f"{k} {v:.2f}" for k, v in sorted(out["x_dis_ultrafast"][p].items(), key=lambda kv: -kv[1]))
        print(f"  {p} (x DIS ultrafast; total {out['x_dis_medium'][p]['total']:.2f}x DIS medium, fixed "
              f"{out['x_dis_medium'][p]['fixed']:.2f}x): {parts}", flush=True)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--presets", default="realtime,fastest")
    ap.add_argument("--rounds", type=int, default=30)
    ap.add_argument("--cases", default="fine_320,fine_640,kitti2012_000045,kitti2012_000000")
    ap.add_argument("--base", default="", help="another checkout whose engine runs in the same rounds")
    ap.add_argument("--out", default="")
    args = ap.parse_args()
    timers = Timers()
    install(timers)
    base = load_base(args.base) if args.base else None
    if base is not None:
        install(timers, base[0], base[1])
    presets = args.presets.split(",")
    results = {"command": " ".join(sys.argv), "engine": str(Path(engine.__file__).resolve().parent),
               "base": args.base, "cases": {}}
    for case in args.cases.split(","):
        if case == "fine_320":
            label, f0, f1 = fine_pair((320, 240))
        elif case == "fine_640":
            label, f0, f1 = fine_pair((640, 480))
        else:
            label, f0, f1 = large_pair(case)
        results["cases"][label] = run_case(label, f0, f1, presets, args.rounds, timers, base)
    if args.out:
        Path(args.out).write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
