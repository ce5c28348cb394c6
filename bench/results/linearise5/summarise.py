"""Median per side and config of ab_variants.txt, and each variant's median of per-round ratios to main."""
import collections
import json
import sys

import numpy as np

runs = collections.defaultdict(list)
for line in open(sys.argv[1]):
    side, rest = line.split(" ", 1)
    runs[side].append(json.loads(rest.split(" ", 3)[3]))
keys = list(runs["main"][0])
print("config".ljust(14) + "".join(s.rjust(22) for s in runs))
for k in keys:
    row = k.ljust(14)
    for rs in runs.values():
        med = np.median([r[k] for r in rs])
        ratio = np.median([r[k] / m[k] for r, m in zip(rs, runs["main"], strict=True)])
        row += f"{med:9.3f} ms ({ratio:5.2f}x)".rjust(22)
    print(row)
