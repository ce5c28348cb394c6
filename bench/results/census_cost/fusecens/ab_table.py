"""The before/after table of an interleaved A/B in this folder (FOLDER/{main,fusecens}_rN.json, one bench.census_cost
round per process, the processes alternating main, fusecens, main, ...: ab.sh; FOLDER ab, the default, or
ab_nofreeze, made before bench.census_cost froze the objects after its warm-up): per preset and tree the median
over rounds of the census and grey-value CPU time summed over the large set's 7 pairs, the median of the rounds'
census / grey ratios, the fusion's cost-plane and the ranks' time, and fusecens / main of the census time (median of
the paired rounds' ratios).

    python bench/results/census_cost/fusecens/ab_table.py [FOLDER]
"""

from __future__ import annotations

import json
import statistics
import sys
from pathlib import Path

HERE = Path(__file__).parent
PLANES = ("fuse/census_planes", "fuse/planes", "cost_planes")  # main's spans inside fuse, the branch's backend field
RANKS = ("initialise/equalised", "initialise/ranks")  # main's module function, the branch's backend field


def rounds(folder: Path, tree: str) -> list[dict]:
    files = sorted(folder.glob(f"{tree}_r*.json"), key=lambda p: int(p.stem.split("_r")[1]))
    return [json.loads(p.read_text()) for p in files]


def main() -> None:
    folder = HERE / (sys.argv[1] if len(sys.argv) > 1 else "ab")
    runs = {t: rounds(folder, t) for t in ("main", "fusecens")}
    n = min(len(r) for r in runs.values())
    loads = [r["load_average_start"][0] for t in runs for r in runs[t][:n]]
    print(f"{folder.name}: {n} rounds per tree, {runs['main'][0]['started']} to {runs['fusecens'][n - 1]['started']}; "
          f"1-min load at each process's start {min(loads):.1f}-{max(loads):.1f} (2 cores)")
    print("| preset | tree | grey ms | census ms | census / grey | census cost planes ms | ranks ms |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for preset in ("realtime", "fastest"):
        census_totals = {}
        for tree, rs in runs.items():
            rows = [(r["rounds"][preset]["normalise"][0], r["rounds"][preset]["census"][0]) for r in rs[:n]]
            census_totals[tree] = [c["total"] for _, c in rows]
            grey = statistics.median(g["total"] for g, _ in rows)
            census = statistics.median(c["total"] for _, c in rows)
            ratio = statistics.median(c["total"] / g["total"] for g, c in rows)
            planes = statistics.median(sum(c.get(k, 0.0) for k in PLANES) for _, c in rows)
            eq = statistics.median(sum(c.get(k, 0.0) for k in RANKS) for _, c in rows)
            print(f"| {preset} | {tree} | {1e3 * grey:.0f} | {1e3 * census:.0f} | {ratio:.2f}x | {1e3 * planes:.1f} "
                  f"| {1e3 * eq:.1f} |")
        paired = statistics.median(a / b for a, b in zip(census_totals["fusecens"], census_totals["main"], strict=True))
        print(f"| {preset} | fusecens / main census time | | {paired:.3f}x | | | |")


if __name__ == "__main__":
    main()
