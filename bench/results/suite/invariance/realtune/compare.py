"""Ratio table of bench.suite JSON results against a baseline method (task realtune).

    python3 bench/results/suite/invariance/realtune/compare.py BASE file.json [file2.json ...]

Per regime the mean AEE of every method in the files, its ratio to BASE's (same regime, any file), the worst
ratio and the geometric mean over the regimes BASE has.
"""
import json
import math
import sys

base, files = sys.argv[1], sys.argv[2:]
aee: dict[str, dict[str, float]] = {}
for f in files:
    for reg, rd in json.load(open(f))["regimes"].items():
        for m, md in rd["methods"].items():
            aee.setdefault(m, {})[reg] = md["aee"]
regs = list(aee[base])
print("| method | " + " | ".join(regs) + " | worst | geomean |")
print("|---" * (len(regs) + 3) + "|")
for m, row in aee.items():
    if m == base:
        print(f"| {m} | " + " | ".join(f"{row[r]:.4f}" for r in regs) + " | - | - |")
        continue
    rat = [row[r] / aee[base][r] for r in regs if r in row]
    worst = max(zip(rat, regs, strict=False))
    gm = math.exp(sum(map(math.log, rat)) / len(rat))
    print(f"| {m} | " + " | ".join(f"{row[r] / aee[base][r]:.3f}" if r in row else "-" for r in regs)
          + f" | {worst[1]} {worst[0]:.3f} | {gm:.3f} |")
