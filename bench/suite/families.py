"""Per-family table of a suite result: mean AEE of each method over each photometric family's pairs, and its
ratio to the same method's unchanged pairs (white balance against the unchanged colour pairs).

    python -m bench.suite.families bench/results/suite/invariance/photometric.json photometric_real [regime ...]
"""

from __future__ import annotations

import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from ..common import md_table

COLOUR = ("white_balance", "unchanged rgb")


def family_table(result: dict, regime: str) -> str:
    """The markdown table of ``regime`` in a suite result (bench.suite's JSON)."""
    reg = result["regimes"][regime]
    methods = reg["methods"]
    names = list(methods)
    by_family: dict[str, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    for pair in reg["pairs"]:
        family = pair["variant"].split("/")[0]
        for m in names:
            by_family[family][m].append(methods[m]["per_pair"][pair["name"]]["aee"])
    unchanged = {f: {m: float(np.mean(by_family[f][m])) for m in names} for f in ("unchanged", "unchanged rgb")
                 if f in by_family}
    rows = []
    for family, values in by_family.items():
        base = unchanged.get("unchanged rgb" if family in COLOUR else "unchanged", unchanged["unchanged"])
        cells = [f"{np.mean(values[m]):.3f} ({np.mean(values[m]) / base[m]:.2f}x)" for m in names]
        rows.append([family, *cells])
    return "\n".join(md_table(["family", *names], rows, right=True))


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) < 2:
        print(__doc__.strip().splitlines()[-1].strip(), file=sys.stderr)
        return 2
    result = json.loads(Path(args[0]).read_text())
    for regime in args[1:]:
        print(f"{regime}\n\n{family_table(result, regime)}\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
