"""The table of summary.md from time_colour.py's JSON files: per pair, the medians over every run and repeat.

    python summarise.py DIR PREFIX     # DIR/PREFIX_main_*.json against DIR/PREFIX_photoapi_*.json"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np


def load(folder: Path, prefix: str, label: str) -> tuple[int, dict[str, float], dict[str, float]]:
    runs = [json.loads(f.read_text()) for f in sorted(folder.glob(f"{prefix}_{label}_*.json"))]
    pairs = runs[0]["pairs"].keys()
    est = {p: float(np.median([t for r in runs for t in r["pairs"][p]["estimate_s"]])) for p in pairs}
    stage = {p: float(np.median([t for r in runs for t in r["pairs"][p]["stage_s"]])) for p in pairs}
    return len(runs), est, stage


def main() -> None:
    folder, prefix = Path(sys.argv[1]), sys.argv[2]
    nm, em, sm = load(folder, prefix, "main")
    nb, eb, sb = load(folder, prefix, "photoapi")
    print(f"runs: main {nm}, photoapi {nb}; medians over the runs x repeats")
    print("| pair | estimate main s | photoapi s | ratio | stage main ms | photoapi ms | saved ms |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    rows = [(p.split("/")[0], em[p], eb[p], sm[p], sb[p]) for p in em]
    rows.append(("all (sum of medians)", sum(em.values()), sum(eb.values()), sum(sm.values()), sum(sb.values())))
    for name, a, b, sa, so in rows:
        print(f"| {name} | {a:.3f} | {b:.3f} | {b / a:.3f} | {1e3 * sa:.2f} | {1e3 * so:.2f} | {1e3 * (sa - so):.2f} |")


if __name__ == "__main__":
    main()
