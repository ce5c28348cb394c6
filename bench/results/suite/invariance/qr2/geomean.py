"""Per regime, each method's mean AEE and its ratio to a base method; their geomean (a bench.suite JSON)."""
import json
import math
import sys

data = json.load(open(sys.argv[1]))
base = sys.argv[2]
regimes = data["regimes"]
methods = list(next(iter(regimes.values()))["methods"])
print("| regime | " + " | ".join(methods) + " |")
ratios: dict[str, list[float]] = {m: [] for m in methods}
for name, regime in regimes.items():
    b = regime["methods"][base]["aee"]
    row = []
    for m in methods:
        a = regime["methods"][m]["aee"]
        ratios[m].append(a / b)
        row.append(f"{a:.4f} ({a / b:.3f})")
    print(f"| {name} | " + " | ".join(row) + " |")
cells = [f"{math.exp(sum(map(math.log, r)) / len(r)):.4f} / worst {max(r):.3f}" for r in ratios.values()]
print("| geomean | " + " | ".join(cells) + " |")
