"""Per-family mean AEE (and / unchanged) of the census methods in suite runs: python fam.py RUN.json ..."""
import json
import sys
from collections import defaultdict

for path in sys.argv[1:]:
    res = json.load(open(path))
    for reg, r in res["regimes"].items():
        ms = r["methods"]
        if not any("/" in v for m in ms.values() for v in m.get("per_variant", {})):
            continue
        print(f"\n{path.split('/')[-1]} {reg}")
        fams = None
        rows = {}
        for name, m in ms.items():
            pv = m["per_variant"]
            fam = defaultdict(list)
            for v, x in pv.items():
                fam["unchanged" if v.startswith("unchanged") and v != "unchanged rgb" else
                    ("unchanged rgb" if v == "unchanged rgb" else v.split("/")[0])].append(x["aee"])
            rows[name] = {f: sum(x) / len(x) for f, x in fam.items()}
            fams = list(rows[name])
        print("| method | " + " | ".join(fams) + " |")
        print("|---|" + "---:|" * len(fams))
        for name, row in rows.items():
            u = row["unchanged"]
            cells = [f"{row[f]:.4f}" + ("" if f.startswith("unchanged") else
                     f" ({row[f] / row.get('unchanged rgb' if f == 'white_balance' else 'unchanged', u):.2f}x)")
                     for f in fams]
            print(f"| {name} | " + " | ".join(cells) + " |")
