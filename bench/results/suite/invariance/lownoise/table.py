"""The diagnosis table from oracle.py's runs: per preset and regime the clean AEE, the noisy one (ratio), and for each
oracle its AEE and the share of the gap noisy - clean it closes (negative: it widens it).

    python bench/results/suite/invariance/lownoise/table.py oracle_quality.json oracle_balanced.json ...
"""

import json
import sys

SHORT = {"photometric_real": "Middlebury", "real_exact_photometric": "real photos", "photometric": "fine textures"}

files = sys.argv[1:]
runs = [json.load(open(f)) for f in files]
oracles = [o for o in runs[0]["oracles"] if o != "none"]
print("| preset | regime | clean | noisy (ratio) | " + " | ".join(oracles) + " |")
print("|---|---|---:|---:|" + "---:|" * len(oracles))
for r in runs:
    for regime, m in r["summary"].items():
        gap = m["none"] - m["clean"]
        cells = [f"{m[o]:.4f} ({100 * (m['none'] - m[o]) / gap:+.0f} %)" for o in oracles]
        head = f"| {r['preset']} | {SHORT[regime]} | {m['clean']:.4f} | {m['none']:.4f} ({m['none'] / m['clean']:.2f}x)"
        print(head + " | " + " | ".join(cells) + " |")
