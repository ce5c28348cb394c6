"""Per-bag mean AEE of the methods of a bench.suite JSON's ``bags`` regime (tasks fastdelta and fastbags).

    python bench/results/suite/invariance/fastbags/bags.py FILE.json
"""

from __future__ import annotations

import json
import sys

with open(sys.argv[1]) as f:
    methods = json.load(f)["regimes"]["bags"]["methods"]
names = list(methods)
scenes: dict[str, dict[str, list[float]]] = {}
for m in names:
    for pair, v in methods[m]["per_pair"].items():
        scenes.setdefault(pair.rsplit("_", 1)[0], {}).setdefault(m, []).append(v["aee"])
print("| bag | " + " | ".join(names) + " |")
print("|---|" + "---:|" * len(names))
for s, per in sorted(scenes.items()):
    print(f"| {s} | " + " | ".join(f"{sum(per[m]) / len(per[m]):.4f}" for m in names) + " |")
n = len(methods[names[0]]["per_pair"])
print(f"| mean ({n} pairs) | " + " | ".join(f"{methods[m]['aee']:.4f}" for m in names) + " |")
