"""Per-pair AEE of one regime, each method against a base method (task balcens3).

usage: python perpair.py REGIME BASE FILE.json [FILE.json ...]"""
import json
import sys

reg, base, files = sys.argv[1], sys.argv[2], sys.argv[3:]
pp = {}
for f in files:
    r = json.load(open(f))["regimes"].get(reg)
    if r is None:
        continue
    for m, v in r["methods"].items():
        pp.setdefault(m, {}).update({k: p["aee"] for k, p in v["per_pair"].items()})
pairs = list(pp[base])
methods = [m for m in pp if m != base]
print("| pair | " + base + " | " + " | ".join(methods) + " |")
print("|---|---:|" + "---:|" * len(methods))
for k in pairs:
    b = pp[base][k]
    cells = [f"{pp[m][k]:.4f} ({100 * (pp[m][k] / b - 1):+.0f} %)" if k in pp[m] else "-" for m in methods]
    print(f"| {k} | {b:.4f} | " + " | ".join(cells) + " |")
