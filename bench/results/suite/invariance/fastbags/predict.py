"""The bags' mean AEE a tune-scene candidate would give if each bag moved by its tune scene kind's ratio (task
fastbags, issue 25; a rough proxy: the bags are report data and are not run here).

    python bench/results/suite/invariance/fastbags/predict.py SWEEP.txt [SWEEP.txt ...]

SWEEP.txt: tuneset.py output with the five kinds (deformation,rotation,zoom,translation,objects) and a ``census``
row (main's fastest census). Bag values: fastdelta's report run of that setting (git show
4983857:bench/results/suite/invariance/fastdelta/report/report_bags.md), pairs per bag from its JSON.
"""

from __future__ import annotations

import sys

BAGS = {"deformation": (0.1265, 5), "rotation": (0.0693, 5), "zoom": (0.0845, 5), "translation": (0.0284, 5),
        "objects": (0.2083, 9)}
GREY = 0.1075
rows: dict[str, dict[str, float]] = {}
for path in sys.argv[1:]:
    with open(path) as f:
        lines = [ln.strip() for ln in f if " | " in ln]
    head = [c.strip() for c in lines[0].split("|")]
    for ln in lines[1:]:
        cells = [c.strip() for c in ln.split("|")]
        rows[cells[0]] = {k: float(v) for k, v in zip(head[1:], cells[1:], strict=False) if k in BAGS}
base = rows["census"]
n = sum(c for _, c in BAGS.values())
print("| candidate | tune mean | predicted bags | vs grey 0.1075 |")
print("|---|---:|---:|---:|")
for name, r in rows.items():
    bags = sum(v * c * r[k] / base[k] for k, (v, c) in BAGS.items()) / n
    print(f"| {name} | {sum(r.values()) / len(r):.4f} | {bags:.4f} | {bags / GREY:.3f} |")
