"""A comparison table of suite runs for the census study (issue 25): per regime each method's mean AEE
and its AEE and time as ratios against a reference method of the same run (the same preset with grey values).

    python -m bench.census_table bench/results/census_study/report_schedule.json [more.json] \\
        --ref rt_census=rt_grey --ref rt_T=rt_grey ...

``--ref M=R``: compare method M against R (both in one run: the suite interleaves their timed runs). Without
``--ref`` every method is listed with its AEE only. Prints Markdown.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any


def rows(runs: list[dict[str, Any]], refs: dict[str, str]) -> list[str]:
    """Markdown rows: method, reference, then per regime 'AEE (AEE ratio, time ratio)', then the geometric
    means of both ratios over the regimes."""
    regimes = {name: r for run in runs for name, r in run["regimes"].items()}
    out = ["| method | vs | " + " | ".join(regimes) + " | AEE ratio (geomean) | time ratio (geomean) |",
           "|---|---|" + "---:|" * (len(regimes) + 2)]
    methods = list(dict.fromkeys(m for r in regimes.values() for m in r["methods"]))
    for m in methods:
        ref = refs.get(m)
        cells, la, lt = [], [], []
        for r in regimes.values():
            got = r["methods"].get(m)
            if got is None:
                cells.append("-")
                continue
            if ref is None or ref not in r["methods"]:
                cells.append(f"{got['aee']:.4f}")
                continue
            base = r["methods"][ref]
            ra, rt = got["aee"] / base["aee"], got["seconds"] / base["seconds"]
            la.append(math.log(ra))
            lt.append(math.log(rt))
            cells.append(f"{got['aee']:.4f} ({ra:.2f}, {rt:.2f}x)")
        mean = (f"{math.exp(sum(la) / len(la)):.3f} | {math.exp(sum(lt) / len(lt)):.2f}x" if la else "- | -")
        out.append(f"| {m} | {ref or '-'} | " + " | ".join(cells) + f" | {mean} |")
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", type=Path)
    ap.add_argument("--ref", action="append", default=[], help="METHOD=REFERENCE (repeatable)")
    args = ap.parse_args(argv)
    runs = [json.loads(p.read_text()) for p in args.runs]
    refs = dict(pair.split("=", 1) for pair in args.ref)
    print("\n".join(rows(runs, refs)))


if __name__ == "__main__":
    main()
