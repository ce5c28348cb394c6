"""The documented K rule on a suite JSON: per regime the mean AEE per K, its change against K = 2, and the
largest K whose every regime is within max(0.001 px, 0.5 %) of K = 2's.

    python bench/results/suite/invariance/noisek/rule.py tune_quality.json [more.json ...]
Methods are named <letter><K without dot> (q15, q2, q25, ...), as tune.sh names them."""

from __future__ import annotations

import json
import sys


def k_of(name: str) -> float:
    """'q25' -> 2.5, 'r15' -> 1.5, 'f6' -> 6."""
    digits = name[1:]
    return float(digits[0] + "." + digits[1:]) if len(digits) > 1 else float(digits)


def main(paths: list[str]) -> None:
    for path in paths:
        regimes = json.load(open(path))["regimes"]
        names = sorted(next(iter(regimes.values()))["methods"], key=k_of)
        base = next(n for n in names if k_of(n) == 2.0)
        print(f"\n{path}\n\n| regime | " + " | ".join(f"K {k_of(n):g}" for n in names) + " |")
        print("|---|" + "---:|" * len(names))
        ok = {n: True for n in names}
        for reg, r in regimes.items():
            b = r["methods"][base]["aee"]
            cells = []
            for n in names:
                a = r["methods"][n]["aee"]
                tol = max(0.001, 0.005 * b)
                bad = a - b > tol
                ok[n] &= not bad
                cells.append(f"{a:.4f}" + ("" if n == base else f" ({100 * (a / b - 1):+.1f} %{'!' if bad else ''})"))
            print(f"| {reg} | " + " | ".join(cells) + " |")
        within = [k_of(n) for n in names if ok[n]]
        print(f"\nwithin the tolerance of K = 2 on every regime: {within}; rule's K (largest): {max(within):g}")


if __name__ == "__main__":
    main(sys.argv[1:])
