"""Accuracy on the Middlebury training pairs (issue 2): every model and preset beside the peers, one run.

    python -m bench.accuracy                       # all configs + peers -> bench/results/accuracy/accuracy.json
    python -m bench.accuracy --search quality      # the documented preset search -> accuracy_search_quality.json
    python -m bench.accuracy --only l1_tv --no-peers --set iterations=30   # ad hoc

Full-scale frames 10 -> 11, coarse-to-fine on. AEE in px and AE in degrees (Middlebury definitions, unknown
ground truth excluded), per sequence and mean, plus seconds per pair (after a warm-up, so numba JIT time is
not counted). Peers: OpenCV DualTVL1 (defaults), scikit-image TV-L1 (defaults), OpenCV DIS (medium).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from flow_node.core.config import MODELS, PRESETS, FlowConfig

from .common import (
    DEFAULT_DATA,
    PEERS,
    REPO,
    SEQUENCES,
    backend_of,
    evaluate,
    flow_node_method,
    load_middlebury,
    machine,
    write_json,
)

RESULTS = REPO / "bench" / "results" / "accuracy"

# The most accurate setting found (not a preset: ~2.5x the quality preset's iterations per level).
ACCURATE = dict(model="l1_tv", warps=5, iterations=50, level_alpha_factor=0.65)


def configs() -> dict[str, FlowConfig]:
    """What the benchmark runs: each model on the quality preset with its calibrated weights (choosing the
    model brings them, config.MODEL_WEIGHTS), the most accurate setting found, then every preset."""
    quality = FlowConfig.preset("quality")
    out = {f"model:{m}": quality.replace(model=m) for m in MODELS}
    out["tuned:l1_tv_accurate"] = quality.replace(**ACCURATE)
    out.update({f"preset:{name}": FlowConfig.preset(name) for name in PRESETS})
    return out


# The preset search: one knob at a time from the current preset, keeping a change only if it lowers the
# mean AEE (coordinate descent, one pass). Each step lists the values tried for one field.
SEARCH_STEPS: list[tuple[str, list[Any]]] = [
    ("alpha", [0.015, 0.02, 0.03, 0.04]),
    ("median_filter", [0, 3]),
    ("scale_factor", [0.65, 0.8]),
    ("warps", [3, 8]),
    ("level_alpha_factor", [0.8, 1.25]),
    ("iterations", [30, 80]),
]


# The per-model weight search: each model with the default pyramid (FlowConfig(model=m)), its weight(s)
# over a grid; the best become config.MODEL_WEIGHTS (the issue-11 target: every model at its default
# weight within 10 % of its best). alpha first (alpha1 at its calibrated value), then alpha1.
MODEL_GRID: dict[str, list[dict[str, Any]]] = {
    "l2_l2": [dict(alpha=a) for a in (0.0003, 0.001, 0.003, 0.01)],
    "l2_tv": [dict(alpha=a) for a in (0.00005, 0.0002, 0.0008, 0.003)],
    "l1_tv": [dict(alpha=a) for a in (0.02, 0.03, 0.05, 0.08)],
    "l1_tv_l2": [dict(alpha=a) for a in (0.02, 0.03, 0.05)] + [dict(alpha1=a) for a in (0.1, 2.0)],
    "l1_tv_tv": [dict(alpha=a) for a in (0.02, 0.03, 0.05)] + [dict(alpha1=a) for a in (0.03, 0.3)],
}


def model_search(pairs: list, overrides: list[str]) -> dict[str, Any]:
    """Every model over its MODEL_GRID entries on the default pyramid; alpha1 steps start from the best
    alpha. Returns the log and the best per model."""
    out: dict[str, Any] = {"steps": [], "best": {}}
    for model, grid in MODEL_GRID.items():
        base = FlowConfig(model=model).with_overrides(overrides)
        best = None
        for change in grid:
            if "alpha1" in change and best is not None:
                change = {**best[0], **change}
            cfg = base.replace(**change)
            res = _brief(evaluate(flow_node_method(cfg), pairs))
            out["steps"].append({"model": model, "change": change, **res})
            print(f"{model} {change} {res['mean_aee']}", flush=True)
            if best is None or res["mean_aee"] < best[1]["mean_aee"]:
                best = (change, res)
        out["best"][model] = {"change": best[0], **best[1]}
    return out


def levels_for(cfg: FlowConfig) -> int:
    """Enough pyramid levels for the Middlebury sizes (~380 px short side) to reach min_size at this scale."""
    n = 1
    while 388 * cfg.scale_factor**n >= cfg.min_size and n < 30:
        n += 1
    return n


def search(base: FlowConfig, pairs: list, log: list[dict[str, Any]]) -> FlowConfig:
    """Coordinate descent over SEARCH_STEPS from ``base``; every evaluation is appended to ``log``."""
    best = base
    best_res = evaluate(flow_node_method(best), pairs)
    log.append({"config": best.to_dict(), **_brief(best_res)})
    print(f"start  {_brief(best_res)}", flush=True)
    for name, values in SEARCH_STEPS:
        for value in values:
            change: dict[str, Any] = {name: value}
            if name == "scale_factor":
                change["levels"] = levels_for(best.replace(scale_factor=value))
            cand = best.replace(**change)
            res = evaluate(flow_node_method(cand), pairs)
            log.append({"config": cand.to_dict(), "change": change, **_brief(res)})
            print(f"{change}  {_brief(res)}", flush=True)
            if res["mean_aee"] < best_res["mean_aee"]:
                best, best_res = cand, res
    print(f"best {best.to_dict()} {_brief(best_res)}")
    return best


def _brief(res: dict[str, Any]) -> dict[str, Any]:
    return {"mean_aee": round(res["mean_aee"], 4), "mean_ae": round(res["mean_ae"], 3),
            "mean_seconds": round(res["mean_seconds"], 3),
            "aee": {k: round(v["aee"], 3) for k, v in res["per_sequence"].items()}}


def markdown(payload: dict[str, Any]) -> str:
    """The per-sequence AEE table (and mean AEE, AE, seconds, time ratio to DualTVL1) of an accuracy JSON."""
    results = payload["results"]
    seqs = payload["sequences"]
    ref = results.get("peer:opencv_dualtvl1", {}).get("mean_seconds")
    head = ["config"] + [s[:9] for s in seqs] + ["mean AEE", "mean AE (deg)", "s / pair", "time / DualTVL1"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, r in results.items():
        per = r["per_sequence"]
        ratio = f"{r['mean_seconds'] / ref:.3f}" if ref else "-"
        cells = [name] + [f"{per[s]['aee']:.3f}" for s in seqs]
        cells += [f"**{r['mean_aee']:.3f}**", f"{r['mean_ae']:.2f}", f"{r['mean_seconds']:.2f}", ratio]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="Middlebury folder (<Seq>/frame10.png ...)")
    ap.add_argument("--only", nargs="*", help="config names to run (e.g. l1_tv preset:quality)")
    ap.add_argument("--no-peers", action="store_true", help="skip the peer methods")
    ap.add_argument("--sequences", nargs="*", default=list(SEQUENCES))
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE", help="override every config")
    ap.add_argument("--search", metavar="PRESET", help="run the preset search from PRESET instead")
    ap.add_argument("--model-search", action="store_true", help="run the per-model weight search instead")
    ap.add_argument("--output", type=Path, help="JSON file (default bench/results/accuracy/accuracy*.json)")
    ap.add_argument("--markdown", type=Path, metavar="JSON", help="print the table of a results file and exit")
    args = ap.parse_args(argv)
    if args.markdown:
        import json

        print(markdown(json.loads(args.markdown.read_text())))
        return
    pairs = load_middlebury(args.data, tuple(args.sequences))

    if args.search:
        log: list[dict[str, Any]] = []
        best = search(FlowConfig.preset(args.search).with_overrides(args.set), pairs, log)
        out = args.output or RESULTS / f"accuracy_search_{args.search}.json"
        write_json(out, {"command": _command(argv), "machine": machine(), "backend": backend_of(best),
                         "steps": log, "best": best.to_dict()})
        return

    if args.model_search:
        out = args.output or RESULTS / "accuracy_models.json"
        write_json(out, {"command": _command(argv), "machine": machine(), **model_search(pairs, args.set)})
        return

    results: dict[str, Any] = {}
    for name, cfg in configs().items():
        short = name.split(":", 1)[1]
        if args.only and name not in args.only and short not in args.only:
            continue
        cfg = cfg.with_overrides(args.set)
        res = evaluate(flow_node_method(cfg), pairs)
        results[name] = {"config": cfg.to_dict(), "backend": backend_of(cfg), **res}
        print(f"{name:22s} {_brief(res)}", flush=True)
    if not args.no_peers:
        for name, make in PEERS.items():
            res = evaluate(make(), pairs)
            results[f"peer:{name}"] = res
            print(f"peer:{name:17s} {_brief(res)}", flush=True)
    out = args.output or RESULTS / "accuracy.json"
    write_json(out, {"command": _command(argv), "machine": machine(), "sequences": args.sequences,
                     "results": results})


def _command(argv: list[str] | None) -> str:
    import sys

    return "python -m bench.accuracy " + " ".join(argv if argv is not None else sys.argv[1:])


if __name__ == "__main__":
    main()
