"""Accuracy of each model on the Middlebury training pairs, and the weight search behind config.MODEL_WEIGHTS.

    python -m bench.accuracy                  # each model, quality's schedule -> bench/results/accuracy/accuracy.json
    python -m bench.accuracy --model-search   # each model's weight grid -> accuracy_models.json

Full-scale frames 10 -> 11. AEE in px and AE in degrees (Middlebury definitions, unknown ground truth
excluded), per sequence and mean, plus seconds per pair after a warm-up. The presets and the peers on the same
pairs: the suite's ``middlebury`` regime (``python -m bench.suite --regimes middlebury``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from flow_node.core.config import MODELS, FlowConfig

from .common import (
    DEFAULT_DATA,
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


def brief(res: dict[str, Any]) -> dict[str, Any]:
    """Means and per-sequence AEE of an :func:`bench.common.evaluate` result, rounded for the log."""
    return {"mean_aee": round(res["mean_aee"], 4), "mean_ae": round(res["mean_ae"], 3),
            "mean_seconds": round(res["mean_seconds"], 3),
            "aee": {k: round(v["aee"], 3) for k, v in res["per_sequence"].items()}}


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
            res = brief(evaluate(flow_node_method(base.replace(**change)), pairs))
            out["steps"].append({"model": model, "change": change, **res})
            print(f"{model} {change} {res['mean_aee']}", flush=True)
            if best is None or res["mean_aee"] < best[1]["mean_aee"]:
                best = (change, res)
        out["best"][model] = {"change": best[0], **best[1]}
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="Middlebury folder (<Seq>/frame10.png ...)")
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE", help="override every config")
    ap.add_argument("--model-search", action="store_true", help="run the per-model weight search instead")
    ap.add_argument("--output", type=Path, help="JSON file (default bench/results/accuracy/accuracy*.json)")
    args = ap.parse_args(argv)
    pairs = load_middlebury(args.data)
    command = "python -m bench.accuracy " + " ".join(argv if argv is not None else sys.argv[1:])
    if args.model_search:
        out = args.output or RESULTS / "accuracy_models.json"
        write_json(out, {"command": command, "machine": machine(), **model_search(pairs, args.set)})
        return
    results: dict[str, Any] = {}
    for model in MODELS:  # choosing the model brings its calibrated weights (config.MODEL_WEIGHTS)
        cfg = FlowConfig.preset("quality").replace(model=model).with_overrides(args.set)
        res = evaluate(flow_node_method(cfg), pairs)
        results[f"model:{model}"] = {"config": cfg.to_dict(), "backend": backend_of(cfg), **res}
        print(f"{model:10s} {brief(res)}", flush=True)
    write_json(args.output or RESULTS / "accuracy.json", {"command": command, "machine": machine(),
                                                          "sequences": list(SEQUENCES), "results": results})


if __name__ == "__main__":
    main()
