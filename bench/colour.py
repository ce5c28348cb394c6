"""Colour against grey (issue 25, item 4): the suite's pairs that come in colour, and their grey versions.

From the suite's regimes with colour (report split): ``photometric_real`` and ``real_exact_photometric``
(the pairs unchanged in grey and in RGB, and RGB under white balance), ``real_exact`` (grey and RGB pairs)
and ``photometric`` (exact RGB renders of fine textures). Per preset three flow_node configs: the preset as
shipped (``normalise``: grey values of the luma), ``census`` on the luma, and ``census`` with ``colour =
channels`` (the signatures of R, G and B: core/colour.py); OpenCV DIS medium (grey) times alongside. Each
pair is timed round-robin as in the suite (bench.suite.runner.run_pair); time ratios are against DIS medium
in the same run, per group (the machine may be loaded).

    python -m bench.colour --presets realtime,fastest --out bench/results/colour/colour_fast.json
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import time
from collections import defaultdict
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from flow_node.core.config import FlowConfig

from .suite.data import Sample
from .suite.methods import DIS_MEDIUM, build
from .suite.regimes import REGIMES
from .suite.runner import run_pair

COLOUR_REGIMES = ("photometric_real", "real_exact", "real_exact_photometric", "photometric")
CENSUS_ALPHA = {"quality": 0.045}  # docs/engine.md, "Presets": quality's alpha with census
RESULTS = Path(__file__).resolve().parent / "results" / "colour"


def colour_samples(regime: str, split: str) -> Iterator[Sample]:
    """The regime's RGB samples and the grey samples of the same pairs (``X_unchanged`` of ``X_rgb_unchanged``,
    ``X`` of ``X_rgb``)."""
    samples = list(REGIMES[regime].build(split, False))
    names = {s.name for s in samples}
    for s in samples:
        stem = s.name.removesuffix("_unchanged")
        if s.f0.ndim == 3 or stem + "_rgb" + s.name[len(stem):] in names:
            yield s


def configs(presets: list[str]) -> dict[str, FlowConfig]:
    """Per preset: as shipped, census on the luma, census on the colour channels."""
    out = {}
    for p in presets:
        base = FlowConfig.preset(p)
        census = base.with_overrides(["photometric=census"] + ([f"alpha={CENSUS_ALPHA[p]}"] if p in CENSUS_ALPHA
                                                              else []))
        out[p] = base
        out[f"{p}_census"] = census
        out[f"{p}_census_rgb"] = census.with_overrides(["colour=channels"])
    return out


def group_of(regime: str, sample: Sample) -> str:
    """A row of the table: the regime and the variant, white balance's two gains together."""
    variant = "white balance (rgb)" if sample.variant.startswith("white_balance") else sample.variant
    return f"{regime} / {variant}"


def summarise(rows: dict[str, list[dict[str, dict[str, Any]]]], names: list[str]) -> dict[str, dict[str, Any]]:
    """Per group and method: mean AEE, mean seconds and their ratio to DIS medium's mean seconds."""
    out: dict[str, dict[str, Any]] = {}
    for group, pairs in rows.items():
        dis = float(np.mean([p[DIS_MEDIUM]["seconds"] for p in pairs]))
        out[group] = {"pairs": len(pairs)}
        for n in names:
            seconds = float(np.mean([p[n]["seconds"] for p in pairs]))
            out[group][n] = {"aee": float(np.mean([p[n]["aee"] for p in pairs])), "seconds": seconds,
                             "time_vs_dis_medium": seconds / dis}
    return out


def markdown(res: dict[str, Any]) -> str:
    names = res["methods"]
    lines = [f"`{res['command']}` ({res['started']}, load {res['load_average_start'][0]:.1f} -> "
             f"{res['load_average_end'][0]:.1f})", "",
             "| group | pairs | " + " | ".join(names) + " |", "|---|---:|" + "---:|" * len(names)]
    for group, row in res["groups"].items():
        cells = [f"{row[n]['aee']:.3f} ({row[n]['time_vs_dis_medium']:.1f}x)" for n in names]
        lines.append(f"| {group} | {row['pairs']} | " + " | ".join(cells) + " |")
    lines += ["", "Mean AEE px (mean time / DIS medium's mean time in the same run)."]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.colour", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--presets", default="realtime,fastest,quality")
    ap.add_argument("--regimes", default=",".join(COLOUR_REGIMES))
    ap.add_argument("--split", default="report", choices=("tune", "report", "all"))
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--out", type=Path, default=RESULTS / "colour.json")
    args = ap.parse_args(argv)
    cfgs = configs(args.presets.split(","))
    made = build(cfgs, (DIS_MEDIUM,))
    names = [*cfgs, DIS_MEDIUM]
    rows: dict[str, list[dict[str, dict[str, Any]]]] = defaultdict(list)
    res: dict[str, Any] = {"command": "python -m bench.colour " + shlex.join(sys.argv[1:] if argv is None else argv),
                           "started": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
                           "load_average_start": os.getloadavg(), "methods": names, "per_pair": {}}
    turn = 0
    for regime in args.regimes.split(","):
        for sample in colour_samples(regime, args.split):
            pair = run_pair(made, sample, args.repeats, 1, 1e9, turn)
            turn += 1
            rows[group_of(regime, sample)].append(pair)
            res["per_pair"][f"{regime}/{sample.name}"] = pair
            print(f"{regime} {sample.name}: " + ", ".join(f"{n} {pair[n]['aee']:.3f} {pair[n]['seconds']:.2f}s"
                                                          for n in names), flush=True)
    res["load_average_end"] = os.getloadavg()
    res["groups"] = summarise(rows, names)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(res, indent=1))
    md = markdown(res)
    args.out.with_suffix(".md").write_text(md)
    print(md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
