"""Per-regime mean AEE of every method against a base method and their geometric mean (tasks fastdelta and
fastbags; zoom640's geomean.py without its extra-seed files).

    python bench/results/suite/invariance/fastbags/geomean.py BASE FILE.json [FILE.json ...]

Methods of the same name in several files are merged regime by regime (the AEE is deterministic)."""

from __future__ import annotations

import json
import math
import sys

base, files = sys.argv[1], sys.argv[2:]
aee: dict[str, dict[str, float]] = {}  # regime -> method -> mean AEE
for path in files:
    with open(path) as f:
        for regime, res in json.load(f)["regimes"].items():
            for method, m in res["methods"].items():
                aee.setdefault(regime, {})[method] = m["aee"]
regimes = [r for r in aee if base in aee[r]]
methods = sorted({m for r in regimes for m in aee[r]} - {base})
methods = [m for m in methods if all(m in aee[r] for r in regimes)]
print("| regime | " + base + " AEE | " + " | ".join(methods) + " |")
print("|---|---:|" + "---:|" * len(methods))
for r in regimes:
    print(f"| {r} | {aee[r][base]:.4f} | " + " | ".join(f"{aee[r][m] / aee[r][base]:.3f}" for m in methods) + " |")
geo = [math.exp(sum(math.log(aee[r][m] / aee[r][base]) for r in regimes) / len(regimes)) for m in methods]
worst = [max(aee[r][m] / aee[r][base] for r in regimes) for m in methods]
print("| **geomean** | | " + " | ".join(f"**{g:.4f}**" for g in geo) + " |")
print("| worst regime | | " + " | ".join(f"{w:.3f}" for w in worst) + " |")
