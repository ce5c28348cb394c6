"""lowlight.py REPORT.json ...: low light per photometric regime and method, mean AEE and ratio to unchanged."""
import json, sys
from bench.suite.report import family_means, family_ratios
names = {"photometric_real": "Middlebury", "real_exact_photometric": "real photos moved exactly", "photometric": "fine textures"}
print("| preset / method | " + " | ".join(names.values()) + " |")
print("|---|---:|---:|---:|")
rows = {}
for f in sys.argv[1:]:
    d = json.load(open(f))
    for reg in names:
        means = family_means(d["regimes"][reg]); ratios = family_ratios(means)
        for n in means["low_light"]:
            rows.setdefault(n, []).append(f"{ratios['low_light'][n]:.2f}x ({means['low_light'][n]:.4f} / {means['unchanged'][n]:.4f})")
for n, cells in rows.items():
    print(f"| {n} | " + " | ".join(cells) + " |")
