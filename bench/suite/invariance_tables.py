"""BENCHMARKS.md's invariance tables (issue 25) from the photometric run and the DualTVL1 run on real photographs
(the commands in BENCHMARKS.md, "Invariance"): per regime mean AEE and time against DIS medium, per family the
AEE over the unchanged pairs' on Middlebury / real photographs / fine textures, and the unexplained fraction as a
signal (:func:`bench.suite.report.signal_groups`).

    python -m bench.suite.invariance_tables [PHOTOMETRIC_JSON [DUALTVL1_JSON]]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from ..common import md_table
from .photometric import UNCHANGED, UNCHANGED_RGB
from .report import family_means, family_ratios, misread, signal_groups

RESULTS = Path("bench/results/suite/invariance")
# the columns: grey values, the census default, DIS medium (the methods' names in the run's command)
COLUMNS = {"quality_normalise": "`quality`, grey", "realtime": "realtime", "fastest": "fastest",
           "quality": "**`quality`**", "balanced": "balanced census", "realtime_census": "realtime census",
           "fastest_census": "fastest census", "dis_medium": "DIS medium"}
GROUPS = {"photometric_real": "Middlebury + families (`photometric_real`)",
          "real_exact_photometric": "real photos moved exactly + families",
          "photometric": "fine textures + families (`photometric`)"}


def regime_rows(res: dict[str, Any], dualtvl1: float) -> list[list[str]]:
    """Per regime, each column's mean AEE (time / DIS medium; DIS medium's ms)."""
    labels = {**GROUPS, "real_exact": f"real photos moved exactly (`real_exact`, with DualTVL1: {dualtvl1:.3f})"}
    rows = []
    for regime, label in labels.items():
        methods = res["regimes"][regime]["methods"]
        cells = []
        for n in COLUMNS:
            m = methods[n]
            aee = f"**{m['aee']:.3f}**" if n == "quality" else f"{m['aee']:.3f}"
            cells.append(f"{aee} ({m['seconds'] * 1e3:.1f} ms)" if n == "dis_medium"
                         else f"{aee} ({m['time_vs_dis_medium']:.1f}x)")
        rows.append([label, *cells])
    return rows


def family_rows(res: dict[str, Any]) -> list[list[str]]:
    """Per family, each column's AEE over its unchanged pairs', 'Middlebury / real photos / fine textures'."""
    ratios = {g: family_ratios(family_means(res["regimes"][g])) for g in GROUPS}
    families = [f for f in ratios["photometric"] if f not in (UNCHANGED, UNCHANGED_RGB)]
    return [[f, *(" / ".join(f"{ratios[g][f][n]:.2f}" if f in ratios[g] else "-" for g in GROUPS)
                  for n in COLUMNS)] for f in families]


def signal_rows(res: dict[str, Any]) -> list[list[str]]:
    """Per regime, each flow_node column's pairs on the wrong side of the level over all: 'unchanged, handled,
    wrong' ('-' for none)."""
    rows = []
    for g, label in GROUPS.items():
        cells = []
        for n in list(COLUMNS)[:-1]:
            groups = signal_groups(res["regimes"][g], n)
            cells.append(", ".join(f"{sum(misread(k, u) for u in v)}/{len(v)}" if v else "-"
                                   for k, v in groups.items()))
        rows.append([label.split(" (")[0], *cells])
    return rows


def tables(res: dict[str, Any], dualtvl1: float) -> str:
    """The three tables, Markdown."""
    heads = list(COLUMNS.values())
    return "\n\n".join((
        "\n".join(md_table(["regime", *heads], regime_rows(res, dualtvl1), right=True)),
        "\n".join(md_table(["family (Middlebury / real photos / fine textures)", *heads], family_rows(res),
                           right=True)),
        "\n".join(md_table(["regime: unchanged, handled, wrong", *heads[:-1]], signal_rows(res)))))


def main(argv: list[str] | None = None) -> None:
    args = sys.argv[1:] if argv is None else argv
    photometric = Path(args[0]) if args else RESULTS / "photometric.json"
    dual = Path(args[1]) if len(args) > 1 else RESULTS / "real_exact_dualtvl1.json"
    res = json.loads(photometric.read_text())
    dualtvl1 = json.loads(dual.read_text())["regimes"]["real_exact"]["methods"]["dualtvl1"]["aee"]
    print(tables(res, dualtvl1))


if __name__ == "__main__":
    main()
