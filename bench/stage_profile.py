"""Where a call of the fast presets spends its time: milliseconds per call in each engine stage, beside OpenCV
DIS medium and ultrafast timed on the same frames in the same loop.

    .venv-bench/bin/python -m bench.stage_profile --regimes fine_320,fine_640,large --out bench/results/x.json
    .venv-bench/bin/python -m bench.stage_profile --regimes large --presets "realtime;realtime:init_finest_level=0"

Stages are timed by wrapping the functions the engine calls (photometric stage, initialisation, pyramid, the
per-level warp source, the backend's linearisation and primal-dual iterations, median filters, the state's
resampling between levels, fusion, reliability, output layout); ``other`` is the rest of a call (Python
between the stages, the API's input checks). The wrappers add a few microseconds per call. Fine-texture
regimes use the suite's ``tune`` seeds (quick set: 4 pairs), ``large`` the pairs of ../shared/data/large.
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2

from flow_node.core import engine, refine
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig

from .common import machine, to_u8, write_json
from .suite import data, synthetic
from .suite.methods import unit_grey

PRESETS = ("realtime", "fastest")
# (module, function, stage label): functions the engine looks up at call time, wrapped in place
WRAPPED = ((engine, "stage", "photometric"), (engine, "initialise", "initialise"), (engine, "make_pyramid", "pyramid"),
           (engine, "fuse_on_level", "fusion"), (engine, "candidates_on_level", "fusion"),
           (engine, "interleaved_flow", "layout"),
           (refine, "warp_source", "warp_source"), (refine, "median_filter", "median"),
           (refine, "resize_state", "resize_state"), (engine, "resize_state", "resize_state"))
STAGES = ("iterations", "linearise", "median", "warp_source", "resize_state", "pyramid", "photometric",
          "initialise", "fusion", "reliability", "layout")


def samples(regime: str, large: Path) -> list[Any]:
    """The pairs of ``regime``: fine_320 / fine_640 (the suite's quick tune seeds), or large (../shared)."""
    if regime == "large":
        return data.large(False, large)
    return list(synthetic.fine("tune", True, (320, 240) if regime == "fine_320" else (640, 480)))


def timed(fn: Callable[..., Any], label: str, acc: dict[str, float]) -> Callable[..., Any]:
    """``fn`` that adds the seconds of each call to ``acc[label]``."""
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        start = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            acc[label] = acc.get(label, 0.0) + time.perf_counter() - start
    return wrapper


def config(spec: str) -> FlowConfig:
    """``PRESET[:key=value,...]`` -> that preset with the overrides."""
    name, _, overrides = spec.partition(":")
    cfg = FlowConfig.preset(name)
    return cfg.with_overrides(overrides.split(",")) if overrides else cfg


def profile(regime: str, rounds: int, large: Path, presets: tuple[str, ...] = PRESETS) -> dict[str, dict[str, float]]:
    """ms per call of each stage (and the total, DIS medium, DIS ultrafast) per preset spec on ``regime``."""
    pairs = samples(regime, large)
    acc: dict[str, float] = {}
    saved = [(mod, name, getattr(mod, name)) for mod, name, _ in WRAPPED]
    for mod, name, label in WRAPPED:
        setattr(mod, name, timed(getattr(mod, name), label, acc))
    dis = {f"dis_{p.lower()}": cv2.DISOpticalFlow_create(getattr(cv2, f"DISOPTICAL_FLOW_PRESET_{p}"))
           for p in ("MEDIUM", "ULTRAFAST")}
    out = {}
    try:
        for preset in presets:
            est = FlowEstimator(config(preset))
            est.warmup()
            b = est._backend
            est._backend = b._replace(linearise=timed(b.linearise, "linearise", acc),
                                      solve=timed(b.solve, "iterations", acc),
                                      reliability=timed(b.reliability, "reliability", acc))
            for s in pairs:
                est.estimate(s.f0, s.f1)
            acc.clear()
            total = dict.fromkeys(["total", *dis], 0.0)
            for _ in range(rounds):
                for s in pairs:
                    start = time.perf_counter()
                    est.estimate(s.f0, s.f1)
                    total["total"] += time.perf_counter() - start
                    u0, u1 = to_u8(unit_grey(s.f0, s.bits)), to_u8(unit_grey(s.f1, s.bits))
                    for name, algo in dis.items():
                        start = time.perf_counter()
                        algo.calc(u0, u1, None)
                        total[name] += time.perf_counter() - start
            n = rounds * len(pairs)
            row = {k: 1e3 * acc.get(k, 0.0) / n for k in STAGES}
            row.update({k: 1e3 * v / n for k, v in total.items()})
            row["other"] = row["total"] - sum(row[k] for k in STAGES)
            out[preset] = row
    finally:
        for mod, name, fn in saved:
            setattr(mod, name, fn)
    return out


def table(result: dict[str, Any]) -> str:
    """A Markdown table of ``result``: ms per call of each stage, DIS's times and the preset's ratios to them."""
    cols = ("total", *STAGES, "other")
    head = " | ".join(cols) + " | DIS medium | DIS ultrafast | / DIS medium | / DIS ultrafast"
    lines = [f"| regime | preset | {head} |", "|---|---|" + "---:|" * (len(cols) + 4)]
    for regime, per in result["regimes"].items():
        for preset, r in per.items():
            lines.append(f"| {regime} | {preset} | " + " | ".join(f"{r[k]:.2f}" for k in cols)
                         + f" | {r['dis_medium']:.2f} | {r['dis_ultrafast']:.2f} | {r['total'] / r['dis_medium']:.2f}"
                         f" | {r['total'] / r['dis_ultrafast']:.1f} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--regimes", default="fine_320,fine_640,large")
    ap.add_argument("--rounds", type=int, default=8, help="timed passes over the pairs (large: a quarter)")
    ap.add_argument("--large", type=Path, default=data.LARGE_DATA)
    ap.add_argument("--out", type=Path, default=Path("bench/results/stage_profile.json"))
    ap.add_argument("--presets", default=";".join(PRESETS),
                    help="';'-separated PRESET[:key=value,...] specs (default: %(default)s)")
    args = ap.parse_args()
    result = {"command": "python -m bench.stage_profile " + shlex.join(sys.argv[1:]), "machine": machine(),
              "unit": "ms per call", "regimes": {}}
    for regime in args.regimes.split(","):
        rounds = max(1, args.rounds // 4) if regime == "large" else args.rounds
        result["regimes"][regime] = profile(regime, rounds, args.large, tuple(args.presets.split(";")))
    write_json(args.out, result)
    print(table(result))


if __name__ == "__main__":
    main()
