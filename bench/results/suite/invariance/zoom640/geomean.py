"""Per-regime mean AEE of every method against a base method and their geometric mean (task zoom640).

    python bench/results/suite/invariance/zoom640/geomean.py BASE FILE.json [FILE.json ...] [EXTRA.txt ...]

Methods of the same name in several files are merged regime by regime (the AEE is deterministic). EXTRA.txt:
extra640.py's output (more 640x480 tune seeds); with them a regime ``fine_640+`` is added: fine_640's tune pairs
of the JSON files and the extra seeds together, each pair's AEE averaged, in fine_640's place."""

from __future__ import annotations

import json
import math
import sys

base, files = sys.argv[1], sys.argv[2:]
aee: dict[str, dict[str, float]] = {}  # regime -> method -> mean AEE
pairs: dict[str, dict[str, float]] = {}  # method -> pair name -> AEE (fine_640 and the extra seeds)
for path in (f for f in files if f.endswith(".json")):
    for regime, res in json.load(open(path))["regimes"].items():
        for method, m in res["methods"].items():
            aee.setdefault(regime, {})[method] = m["aee"]
            if regime == "fine_640":
                pairs.setdefault(method, {}).update({p: v["aee"] for p, v in m["per_pair"].items()})
extra = [f for f in files if f.endswith(".txt")]
for path in extra:
    lines = [ln.split() for ln in open(path) if ln.strip()]
    names = lines[0][2:]
    for row in lines[1:]:
        if not row[0].startswith("s") or len(row) != len(names) + 2:
            break
        for n, v in zip(names, row[2:], strict=True):
            pairs.setdefault(n, {})[f"{row[0]}_{row[1]}"] = float(v)
if extra:
    full = set.intersection(*(set(p) for p in pairs.values()))
    aee["fine_640+"] = {m: sum(p[k] for k in full) / len(full) for m, p in pairs.items() if full <= set(p)}
    print(f"fine_640+: {len(full)} pairs")
regimes = [r for r in aee if base in aee[r] and not (extra and r == "fine_640")]
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
