"""Candidate configs on the suite's tune split, one run (issue 11 preset tuning).

    python -m bench.sweep OUT.json REGIMES NAME=PRESET:key=value,key=value ...
    python -m bench.sweep bench/results/tune/s4.json middlebury,fine_320 q04=quality:alpha=0.04 rt=realtime

Each NAME=PRESET:overrides is ``FlowConfig.preset(PRESET).with_overrides(...)`` (empty PRESET = FlowConfig()).
Runs ``bench.suite.run_suite(..., split="tune", quick=True)`` with the DIS peers, writes {regime: {method:
{aee, ms, var}}} (var: per-variant AEE for exposure and bit_depth) and prints a table of AEE / ms.
"""

from __future__ import annotations

import json
import sys
from typing import Any

from flow_node.core.config import FlowConfig

from .suite import run_suite


def parse(spec: str) -> tuple[str, FlowConfig]:
    """``NAME=PRESET:k=v,k=v`` -> (name, config)."""
    name, _, rest = spec.partition("=")
    preset, _, overrides = rest.partition(":")
    cfg = FlowConfig.preset(preset) if preset else FlowConfig()
    return name, cfg.with_overrides(overrides.split(",")) if overrides else cfg


def main(argv: list[str] | None = None) -> None:
    args = sys.argv[1:] if argv is None else argv
    out_path, regimes = args[0], args[1].split(",")
    methods = dict(parse(s) for s in args[2:])
    res = run_suite(methods, regimes=regimes, split="tune", quick=True, log=lambda s: None)
    out: dict[str, dict[str, Any]] = {}
    for regime, d in res["regimes"].items():
        for m, v in d["methods"].items():
            e: dict[str, Any] = {"aee": round(v["aee"], 4), "ms": round(v["seconds"] * 1000, 2)}
            if "per_variant" in v and regime in ("exposure", "bit_depth"):
                e["var"] = {k: round(x["aee"], 4) for k, x in v["per_variant"].items()}
            out.setdefault(regime, {})[m] = e
    with open(out_path, "w") as fh:
        json.dump({"command": "python -m bench.sweep " + " ".join(args), "results": out}, fh, indent=1)
    names = list(next(iter(out.values())))
    print("method".ljust(22) + "".join(r[:12].rjust(20) for r in out))
    for m in names:
        print(m.ljust(22) + "".join(f"{out[r][m]['aee']:.4f}/{out[r][m]['ms']:.1f}".rjust(20) for r in out))


if __name__ == "__main__":
    main()
