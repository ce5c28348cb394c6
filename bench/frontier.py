"""The measured frontier of the speed presets against their time targets (issue 11; issue 12's realtime).

    .venv-bench/bin/python -m bench.frontier [--out bench/results/frontier/frontier.json] [--repeats 5] [--keep-freed]
    make bench-frontier                                   # the same, ~3-4 min on a quiet 2-core machine

A ladder of settings around ``realtime`` and ``fastest``, from dearer to much cheaper (fewer and shorter warps,
a coarser finest level, a smaller median, no initialisation gate), runs with DIS ultrafast and DIS medium in
one bench.suite run (report seeds, methods interleaved per pair) on the regimes the two presets' targets use:
fine_320 and fine_640 (AEE and time), middlebury (realtime <= 0.45), bit_depth (10/12/16 bit within 10 % of
8 bit), exposure (every gain <= 1.3x the unchanged pair) and large (issue 12: realtime <= DIS medium's AEE
on ../shared/data/large at <= its time). Every candidate is checked against both families' accuracy targets:

- realtime family: fine-texture AEE <= DIS medium's at both sizes, Middlebury <= 0.45, bit depth, exposure;
  its time target is <= 1x DIS medium's time at both sizes;
- fastest family: fine-texture AEE <= DIS ultrafast's at both sizes, bit depth, exposure; time target
  <= 2x DIS ultrafast's time.

The answer per family: the cheapest candidate that meets every accuracy target, and its time against the
bound. ``--keep-freed`` applies ``flow_node.process.keep_freed_memory`` first, as the node and the CLIs do
(the suite itself keeps glibc's defaults). Writes the JSON, a markdown table beside it and a plot (AEE against
time, both over DIS medium's, per size; filled markers meet the family's other accuracy targets).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from flow_node.core.config import FlowConfig

from .suite.methods import DIS_MEDIUM, DIS_ULTRAFAST
from .suite.runner import run_suite
from .suite.targets import DEPTH_BOUND, EXPOSURE_BOUND, FINE, MIDDLEBURY_BOUNDS, variant_ratios

REGIMES = ("fine_320", "fine_640", "middlebury", "bit_depth", "exposure", "large")

# name -> (base preset, overrides); the shipped presets first, then cheaper steps away from each
CANDIDATES: dict[str, tuple[str, dict[str, Any]]] = {
    "realtime": ("realtime", {}),
    "rt_far_full": ("realtime", {"init_finest_level": 0}),
    "rt_no_gate": ("realtime", {"initialisation": "none"}),
    "rt_1x24": ("realtime", {"finest_warps": 1, "finest_iterations": 24}),
    "rt_1x16": ("realtime", {"finest_warps": 1, "finest_iterations": 16}),
    "rt_1x8": ("realtime", {"finest_warps": 1, "finest_iterations": 8}),
    "rt_4x4_1x4": ("realtime", {"iterations": 4, "finest_warps": 1, "finest_iterations": 4}),
    "rt_lean": ("realtime", {"warps": 2, "iterations": 4, "finest_warps": 1, "finest_iterations": 4,
                             "median_filter": 3, "initialisation": "none"}),
    "rt_half": ("realtime", {"finest_level": 1}),
    "fastest": ("fastest", {}),
    "fa_far_half": ("fastest", {"init_finest_level": 0}),
    "fa_no_gate": ("fastest", {"initialisation": "none"}),
    "fa_2x6": ("fastest", {"warps": 2, "iterations": 6}),
    "fa_lean": ("fastest", {"warps": 2, "iterations": 4, "finest_iterations": 4, "median_filter": 3,
                            "initialisation": "none"}),
    "fa_quarter": ("fastest", {"finest_level": 2}),
    "fa_quarter_lean": ("fastest", {"finest_level": 2, "levels": 4, "warps": 2, "iterations": 4,
                                    "finest_iterations": 4, "median_filter": 3, "initialisation": "none"}),
    "fa_floor": ("fastest", {"finest_level": 2, "levels": 3, "warps": 1, "iterations": 2, "finest_iterations": 2,
                             "median_filter": 0, "initialisation": "none"}),
}

# Each family's targets: fine-texture / large-set AEE <= the peer's on aee_regimes, the time bound against the
# peer on time_regimes (the worse regime counts), and the regime-free accuracy targets (Middlebury for the
# realtime preset; bit depth and exposure for both). "large" is issue 12's realtime target, on top of issue 11's.
FAMILIES: dict[str, dict[str, Any]] = {
    "realtime": {"peer": DIS_MEDIUM, "time_bound": 1.0, "middlebury": MIDDLEBURY_BOUNDS["realtime"],
                 "aee_regimes": FINE, "time_regimes": FINE},
    "fastest": {"peer": DIS_ULTRAFAST, "time_bound": 2.0, "middlebury": None,
                "aee_regimes": FINE, "time_regimes": FINE},
    "large": {"peer": DIS_MEDIUM, "time_bound": 1.0, "middlebury": MIDDLEBURY_BOUNDS["realtime"],
              "aee_regimes": (*FINE, "large"), "time_regimes": ("large",)},
}
RATIO_REGIMES = (*FINE, "large")


def configs() -> dict[str, FlowConfig]:
    """The candidates as configs."""
    return {name: FlowConfig.preset(base).replace(**changes) for name, (base, changes) in CANDIDATES.items()}


def _worst_variant(res: dict[str, Any], regime: str, name: str, ref: str) -> float | None:
    ratios = variant_ratios(res["regimes"][regime]["methods"][name], ref)
    return max(ratios.values()) if ratios else None


def assess(res: dict[str, Any], name: str) -> dict[str, Any]:
    """One candidate: its figures in the run and, per family, the accuracy targets it misses and its time
    ratio against the family's peer (the worse of the family's time regimes)."""
    methods = {regime: r["methods"] for regime, r in res["regimes"].items()}
    row: dict[str, Any] = {
        "middlebury": methods["middlebury"][name]["aee"],
        "bit_depth_ratio": _worst_variant(res, "bit_depth", name, "8 bit"),
        "exposure_ratio": _worst_variant(res, "exposure", name, "unchanged"),
    }
    for regime in RATIO_REGIMES:
        m, peers = methods[regime][name], methods[regime]
        row[regime] = {"aee": m["aee"], "ms": 1e3 * m["seconds"],
                       "aee_vs": {p: m["aee"] / peers[p]["aee"] for p in (DIS_MEDIUM, DIS_ULTRAFAST)},
                       "time_vs": {p: m["seconds"] / peers[p]["seconds"] for p in (DIS_MEDIUM, DIS_ULTRAFAST)}}
    row["families"] = {}
    for fam, spec in FAMILIES.items():
        peer = spec["peer"]
        failed = [f"{r} AEE {row[r]['aee_vs'][peer]:.2f}x" for r in spec["aee_regimes"] if row[r]["aee_vs"][peer] > 1.0]
        if spec["middlebury"] is not None and row["middlebury"] > spec["middlebury"]:
            failed.append(f"Middlebury {row['middlebury']:.3f}")
        if row["bit_depth_ratio"] is not None and row["bit_depth_ratio"] > DEPTH_BOUND:
            failed.append(f"bit depth {row['bit_depth_ratio']:.2f}x")
        if row["exposure_ratio"] is not None and row["exposure_ratio"] > EXPOSURE_BOUND:
            failed.append(f"exposure {row['exposure_ratio']:.2f}x")
        time = max(row[r]["time_vs"][peer] for r in spec["time_regimes"])
        row["families"][fam] = {"accuracy_met": not failed, "failed": failed, "time": time,
                                "met": not failed and time <= spec["time_bound"]}
    return row


def summarise(res: dict[str, Any]) -> dict[str, Any]:
    """From a bench.suite result of this module's run: the candidates' rows, the peers' figures and, per
    family, the cheapest candidate that meets every accuracy target checked and whether any meets the time."""
    rows = {name: assess(res, name) for name in CANDIDATES}
    peers = {regime: {p: {"aee": res["regimes"][regime]["methods"][p]["aee"],
                          "ms": 1e3 * res["regimes"][regime]["methods"][p]["seconds"]}
                      for p in (DIS_MEDIUM, DIS_ULTRAFAST)} for regime in RATIO_REGIMES}
    verdict = {}
    for fam, spec in FAMILIES.items():
        ok = {n: r["families"][fam]["time"] for n, r in rows.items() if r["families"][fam]["accuracy_met"]}
        cheapest = min(ok, key=lambda n: ok[n]) if ok else None
        verdict[fam] = {"peer": spec["peer"], "time_bound": spec["time_bound"], "cheapest_accurate": cheapest,
                        "its_time": ok.get(cheapest) if cheapest else None,
                        "met_by": [n for n, r in rows.items() if r["families"][fam]["met"]]}
    return {"candidates": rows, "peers": peers, "verdict": verdict}


def markdown(result: dict[str, Any]) -> str:
    """The table: one row per candidate, both sizes and the large set, every family."""
    lines = ["| candidate | fine_320 AEE (x DIS med) | time (x DIS med) | fine_640 AEE (x DIS med) | time (x DIS med) "
             "| Middlebury | 10-16 bit / 8 bit | exposure / unchanged | large AEE (x DIS med) | time (x DIS med) | "
             + " | ".join(f"{fam} targets (time x {spec['peer']})" for fam, spec in FAMILIES.items()) + " |",
             "|---|" + "---:|" * 9 + "---|" * len(FAMILIES)]
    for name, r in result["candidates"].items():
        cells = [name]
        for regime in RATIO_REGIMES:
            f = r[regime]
            cells.append(f"{f['aee']:.4f} ({f['aee_vs'][DIS_MEDIUM]:.2f}x)")
            cells.append(f"{f['time_vs'][DIS_MEDIUM]:.2f}x")
            if regime == FINE[-1]:
                cells += [f"{r['middlebury']:.3f}", f"{r['bit_depth_ratio']:.2f}x", f"{r['exposure_ratio']:.2f}x"]
        for fam in FAMILIES:
            fr = r["families"][fam]
            acc = "accuracy met" if fr["accuracy_met"] else "misses " + ", ".join(fr["failed"])
            cells.append(f"{acc}; time {fr['time']:.2f}x" + (" **MET**" if fr["met"] else ""))
        lines.append("| " + " | ".join(cells) + " |")
    peers = result["peers"]
    lines.append("")
    lines.append("Peers (same run): " + "; ".join(
        f"{regime}: DIS medium {peers[regime][DIS_MEDIUM]['aee']:.4f} px at {peers[regime][DIS_MEDIUM]['ms']:.2f} ms, "
        f"DIS ultrafast {peers[regime][DIS_ULTRAFAST]['aee']:.4f} px at {peers[regime][DIS_ULTRAFAST]['ms']:.2f} ms"
        for regime in RATIO_REGIMES) + ".")
    for fam, v in result["verdict"].items():
        bound = f"time bound {v['time_bound']:g}x {v['peer']}"
        if v["met_by"]:
            lines.append(f"- {fam} family ({bound}): met by {', '.join(v['met_by'])}")
        elif v["cheapest_accurate"] is None:
            lines.append(f"- {fam} family ({bound}): no candidate meets every accuracy target checked")
        else:
            lines.append(f"- {fam} family ({bound}): missed by every candidate; the cheapest that meets every "
                         f"accuracy target checked is {v['cheapest_accurate']} at {v['its_time']:.2f}x")
    return "\n".join(lines) + "\n"


def plot(result: dict[str, Any], path: Path) -> None:
    """AEE / DIS medium's against time / DIS medium's (log-log), one panel per size; the target boxes shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8))
    for ax, regime in zip(axes, FINE, strict=True):
        peers = result["peers"][regime]
        uf_t = peers[DIS_ULTRAFAST]["ms"] / peers[DIS_MEDIUM]["ms"]
        uf_a = peers[DIS_ULTRAFAST]["aee"] / peers[DIS_MEDIUM]["aee"]
        ax.fill_between([0.01, 1.0], 0.01, 1.0, color="tab:green", alpha=0.12, label="realtime target")
        ax.fill_between([0.01, 2 * uf_t], 0.01, uf_a, color="tab:orange", alpha=0.12, label="fastest target")
        for name, r in result["candidates"].items():
            fam = "realtime" if CANDIDATES[name][0] == "realtime" else "fastest"
            x, y = r[regime]["time_vs"][DIS_MEDIUM], r[regime]["aee_vs"][DIS_MEDIUM]
            ok = r["families"][fam]["accuracy_met"]
            colour = "tab:green" if fam == "realtime" else "tab:orange"
            ax.scatter(x, y, marker="o", facecolors=colour if ok else "none", edgecolors=colour)
            ax.annotate(name, (x, y), fontsize=7, xytext=(3, 3), textcoords="offset points")
        ax.scatter([1.0, uf_t], [1.0, uf_a], marker="s", c="tab:grey")
        ax.annotate("DIS medium", (1.0, 1.0), fontsize=7, xytext=(3, -9), textcoords="offset points")
        ax.annotate("DIS ultrafast", (uf_t, uf_a), fontsize=7, xytext=(3, -9), textcoords="offset points")
        ax.set(xscale="log", yscale="log", xlim=(0.08, 6), ylim=(0.1, 20), title=regime,
               xlabel="time / DIS medium's (same run)", ylabel="mean AEE / DIS medium's")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    fig.suptitle("Speed presets' frontier: filled = meets its family's other accuracy targets "
                 "(Middlebury, bit depth, exposure)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.frontier", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("bench/results/frontier/frontier.json"))
    ap.add_argument("--repeats", type=int, default=5, help="timed runs per pair and method")
    ap.add_argument("--keep-freed", action="store_true", help="apply keep_freed_memory first, as the node does")
    ap.add_argument("--from-json", action="store_true",
                    help="no run: derive the figures, table and plot again from --out's stored suite result")
    args = ap.parse_args(argv)
    if args.from_json:  # the figures are derived again from the stored suite result
        result = json.loads(args.out.read_text())
        result.update(summarise(result["suite"]))
        args.out.write_text(json.dumps(result, indent=1, default=float))
        write_reports(result, args.out)
        return 0
    if args.keep_freed:
        from flow_node.process import keep_freed_memory

        keep_freed_memory()
    res = run_suite(configs(), regimes=REGIMES, split="report", peers=(DIS_ULTRAFAST, DIS_MEDIUM),
                    repeats=args.repeats)
    result = {"command": "python -m bench.frontier" + (" --keep-freed" if args.keep_freed else "")
              + f" --repeats {args.repeats} --out {args.out}",
              "keep_freed": args.keep_freed, **summarise(res),
              "candidate_settings": {n: {"base": b, **c} for n, (b, c) in CANDIDATES.items()},
              "wall_seconds": res["wall_seconds"], "suite": res}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1, default=float))
    write_reports(result, args.out)
    return 0


def write_reports(result: dict[str, Any], out: Path) -> None:
    """The markdown table and the plot beside ``out``; the table printed."""
    text = markdown(result)
    out.with_suffix(".md").write_text(f"Command: `{result['command']}`\n\n" + text)
    plot(result, out.with_suffix(".png"))
    print(text)


if __name__ == "__main__":
    raise SystemExit(main())
