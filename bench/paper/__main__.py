"""Reproduce the paper's evaluation (issue 6): ``python -m bench.paper`` (or ``make paper``).

Writes bench/results/paper/results.json, the figures (fig1_angular_error.png, fig2_clean.png,
fig2_noisy.png, fig3_flows.png) and regenerates REPORT.md beside them (``--out`` another folder: all there).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from ..common import DEFAULT_DATA, REPO, SEQUENCES, run_record, write_json
from . import figures, report
from .algorithms import BASE, DYNAMIC_FACTORS
from .protocol import RENDERERS, add_noise, consistency, fill_unknown, load_pairs
from .report import KINDS
from .run import FIGURE_SEQUENCES, PRESMOOTH_SIGMA, Runner, ranks, run_peer, run_static_dynamic, run_table2

RESULTS = REPO / "bench" / "results" / "paper"


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="Middlebury folder (<Seq>/frame10.png ...)")
    ap.add_argument("--sequences", nargs="*", default=list(SEQUENCES))
    ap.add_argument("--renderer", default="cubic", choices=RENDERERS,
                    help="second-frame synthesis: cubic (the paper's, default: comparable with its figures) or "
                         "bandlimited (exact for frame 1 read as a band-limited image)")
    ap.add_argument("--out", type=Path, default=RESULTS)
    ap.add_argument("--report-only", action="store_true", help="re-render REPORT.md from results.json and exit")
    args = ap.parse_args(argv)
    if args.report_only:
        results = json.loads((args.out / "results.json").read_text())
        (args.out / "REPORT.md").write_text(report.render(results))
        return
    start = time.perf_counter()
    args.out.mkdir(parents=True, exist_ok=True)

    clean = load_pairs(args.data, tuple(args.sequences), args.renderer)
    noisy = [add_noise(p) for p in clean]
    runner = Runner()
    res: dict[str, Any] = {
        **run_record("bench.paper", argv), "base": BASE, "factors": list(DYNAMIC_FACTORS),
        "presmooth_sigma": PRESMOOTH_SIGMA, "renderer": args.renderer,
        "protocol": {p.name: {"gt_scale": p.scale, "consistency": consistency(p.i0, p.i1, fill_unknown(p.gt))}
                     for p in clean},
    }
    for variant, pairs in (("clean", clean), ("noisy", noisy)):
        out = run_static_dynamic(runner, pairs, DYNAMIC_FACTORS, variant)
        res[variant] = {
            "algorithms": out,
            "peer": {"opencv_dualtvl1": run_peer(pairs, as_float=False),
                     "opencv_dualtvl1_float": run_peer(pairs, as_float=True)},
            "ranks": {f"{kind}_{m}": ranks(out, kind, m) for kind in KINDS for m in ("aee", "ae")},
        }
    dimetrodon = next((p for p in clean if p.name == "Dimetrodon"), None)
    if dimetrodon is not None:
        res["table2"] = run_table2(runner, dimetrodon, (0.0, PRESMOOTH_SIGMA))
    res["figure1"] = figures.figure1(args.out / "fig1_angular_error.png")
    for variant in ("clean", "noisy"):
        figures.figure2(res[variant]["algorithms"], res[variant]["peer"]["opencv_dualtvl1"],
                        args.out / f"fig2_{variant}.png", f"Per-sequence errors, {variant} pairs")
    gts = {p.name: p.gt for p in clean if p.name in FIGURE_SEQUENCES}
    if len(gts) == len(FIGURE_SEQUENCES):
        figures.figure3(runner.flows, gts, "clean", args.out / "fig3_flows.png")
    res["backend"] = sorted(runner.used)
    res["solves"] = runner.solves
    res["solve_seconds"] = runner.seconds
    res["total_seconds"] = time.perf_counter() - start
    write_json(args.out / "results.json", res)
    (args.out / "REPORT.md").write_text(report.render(res))
    print(f"{runner.solves} solves, {res['total_seconds']:.0f} s; wrote {args.out} and REPORT.md")


if __name__ == "__main__":
    main()
