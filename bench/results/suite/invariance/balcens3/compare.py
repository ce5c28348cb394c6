"""Table of mean AEE per regime from suite JSONs, each method against a base method (task balcens2).

usage: python compare.py BASE FILE.json [FILE.json ...]   (BASE: the grey-value method's name in one file)
The geomean leaves out the tone families (grey values fail them by design) and missing (unmasked wiper pairs
fail at random); "worst" is the largest change but photometric_real's."""
import json
import math
import sys

base, files = sys.argv[1], sys.argv[2:]
aee = {}
order = []
for f in files:
    for reg, r in json.load(open(f))["regimes"].items():
        if reg not in order:
            order.append(reg)
        for m, v in r["methods"].items():
            aee.setdefault(m, {})[reg] = v["aee"]
skip = {"photometric_real", "missing", "photometric", "real_exact_photometric"}
print("| method | geomean | worst | " + " | ".join(order) + " |")
print("|---|---:|---:|" + "---:|" * len(order))
for m, row in aee.items():
    cells, logs, worst = [], [], (-1e9, "")
    for reg in order:
        b, v = aee[base].get(reg), row.get(reg)
        if v is None or b is None:
            cells.append("-")
            continue
        ratio = v / b
        tol = max(0.001, 0.005 * b)
        mark = "!" if v - b > tol else ""
        cells.append(f"{v:.4f} ({100 * (ratio - 1):+.1f} %{mark})" if m != base else f"{v:.4f}")
        if reg not in skip:
            logs.append(math.log(ratio))
        if reg != "photometric_real" and m != base and 100 * (ratio - 1) > worst[0]:
            worst = (100 * (ratio - 1), reg)
    g = math.exp(sum(logs) / len(logs)) if logs else float("nan")
    worst_cell = f"{worst[1]} {worst[0]:+.1f} %" if worst[1] else "-"
    print(f"| {m} | {g:.3f} | {worst_cell} | " + " | ".join(cells) + " |")
