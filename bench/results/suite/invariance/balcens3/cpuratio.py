"""CPU time per pair of each method over a base method, per regime (task balcens3). usage: cpuratio.py BASE FILE.json"""
import json
import sys

base, f = sys.argv[1], sys.argv[2]
for reg, r in json.load(open(f))["regimes"].items():
    m = r["methods"]
    g = m[base]["seconds"]
    ratios = ", ".join(f"{k} {v['seconds'] / g:.3f}x" for k, v in m.items() if k != base)
    print(f"{reg}: {base} {1000 * g:.1f} ms/pair, {ratios}")
