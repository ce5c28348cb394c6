"""Tables of the censwin study's runs: python bench/results/suite/invariance/censwin/tables.py RUN.json ...

Per run and method: Middlebury mean AEE (and the shading pairs), bags mean and its deformation pairs, the other
regimes' means, and per photometric regime the worst family's mean AEE over the unchanged pairs' (white
balance over 'unchanged rgb')."""
from __future__ import annotations

import json
import sys
from collections import defaultdict


def family_ratios(m: dict) -> dict[str, float]:
    pv = m.get("per_variant", {})
    fam = defaultdict(list)
    for v, r in pv.items():
        if v.startswith("unchanged"):
            continue
        fam[v.split("/")[0]].append(r["aee"])
    out = {}
    for f, xs in fam.items():
        ref = pv.get("unchanged rgb" if f == "white_balance" else "unchanged", pv.get("unchanged"))["aee"]
        out[f] = sum(xs) / len(xs) / ref
    return out


def main() -> None:
    rows = []
    for path in sys.argv[1:]:
        res = json.load(open(path))
        name = path.split("/")[-1].removesuffix(".json")
        for method in next(iter(res["regimes"].values()))["methods"]:
            cells = {"run": name, "method": method}
            for reg, r in res["regimes"].items():
                m = r["methods"][method]
                cells[reg] = f"{m['aee']:.4f}"
                if reg == "middlebury":
                    pp = m["per_pair"]
                    cells["Dimetrodon/Urban3"] = " / ".join(f"{v['aee']:.3f}" for k, v in pp.items()
                                                           if "Dimetrodon" in k or "Urban3" in k)
                if reg == "bags":
                    d = [v["aee"] for k, v in m["per_pair"].items() if "deform" in k]
                    cells["bags deformation"] = f"{sum(d) / len(d):.4f}" if d else "-"
                if "per_variant" in m and any("/" in v for v in m["per_variant"]):
                    fr = family_ratios(m)
                    worst = max(fr, key=fr.get)
                    cells[reg + " worst family"] = f"{fr[worst]:.2f}x {worst}"
            rows.append(cells)
    cols = list(dict.fromkeys(k for r in rows for k in r))
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for r in rows:
        print("| " + " | ".join(r.get(c, "") for c in cols) + " |")


if __name__ == "__main__":
    main()
