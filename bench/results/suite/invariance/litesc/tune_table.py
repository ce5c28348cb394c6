"""Task litesc's table of a bench.suite JSON: per method each regime's mean AEE (and CPU ms per pair when timed),
R (the worst tune-family ratio over photometric_real and real_exact_photometric: family mean AEE / the same method's
unchanged pairs' mean AEE), the mean of those ratios, the synthetic photometric regime's worst ratio, and each
family's ratio as photometric_real / real_exact_photometric.

Run: python bench/results/suite/invariance/litesc/tune_table.py RUN.json [...]
"""
from __future__ import annotations

import json
import sys
from collections import defaultdict
from typing import Any

FAMILIES = ("gamma", "vignetting", "clipping", "sensor_noise", "s_curve", "log_knee", "illumination", "flicker",
            "white_balance", "low_light")
REAL = ("photometric_real", "real_exact_photometric")


def family_ratios(regime: dict[str, Any], method: str) -> dict[str, float]:
    """Each family's mean AEE over the unchanged pairs' (white balance: the unchanged RGB pairs')."""
    acc: dict[str, list[float]] = defaultdict(list)
    for pair in regime["methods"][method]["per_pair"].values():
        acc[pair["variant"].split("/")[0]].append(pair["aee"])
    mean = {f: sum(a) / len(a) for f, a in acc.items()}
    rgb = mean.get("unchanged rgb", mean["unchanged"])
    return {f: v / (rgb if f == "white_balance" else mean["unchanged"]) for f, v in mean.items() if f in FAMILIES}


def row(regimes: dict[str, Any], method: str) -> str:
    """One method's Markdown row."""
    cells = [method]
    for reg in regimes.values():
        m = reg["methods"][method]
        s = m.get("seconds")
        cells.append(f"{m['aee']:.4f}" + (f" / {s * 1000:.2f}" if isinstance(s, float) and s == s else ""))
    ratios = {(r, f): v for r in REAL if r in regimes for f, v in family_ratios(regimes[r], method).items()}
    worst = max(ratios.values())
    synth = max(family_ratios(regimes["photometric"], method).values()) if "photometric" in regimes else float("nan")
    fams = sorted({f for _, f in ratios}, key=FAMILIES.index)
    cells += [f"**{worst:.3f}**", f"{sum(ratios.values()) / len(ratios):.3f}", f"{synth:.3f}"]
    cells += [f"{ratios.get((REAL[0], f), float('nan')):.2f} / {ratios.get((REAL[1], f), float('nan')):.2f}"
              for f in fams]
    return "| " + " | ".join(cells) + " |"


def main(paths: list[str]) -> None:
    """Print one table per JSON."""
    for path in paths:
        with open(path) as fh:
            regimes = json.load(fh)["regimes"]
        methods = list(next(iter(regimes.values()))["methods"])
        fams = sorted({f for r in REAL if r in regimes for f in family_ratios(regimes[r], methods[0])},
                      key=FAMILIES.index)
        print(f"{path}\n")
        print("| method | " + " | ".join(regimes) + " | R | mean ratio | synthetic worst | "
              + " | ".join(fams) + " |")
        print("|---" * (len(regimes) + 4 + len(fams)) + "|")
        for m in methods:
            print(row(regimes, m))
        print()


if __name__ == "__main__":
    main(sys.argv[1:])
