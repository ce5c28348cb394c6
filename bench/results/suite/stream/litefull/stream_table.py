"""Task litefull's table of ``bench.suite.streams`` JSONs: per method the mean AEE, its ratio to DIS medium's, the CPU
ms per frame and its ratio to ``stream_lite``'s in the same run (frames interleaved), the predicted / fallback counts,
and the mean CPU of the predicted frames and of the full solves (first frames, cuts, fallbacks) apart, from the
per-frame records.

Run: python bench/results/suite/stream/litefull/stream_table.py RUN.json [...]
"""
from __future__ import annotations

import json
import sys
from typing import Any


def split_cpu(run: dict[str, Any], method: str) -> tuple[list[float], list[float]]:
    """The CPU seconds of ``method``'s predicted frames and of its other (fully solved) frames over every sequence."""
    pred: list[float] = []
    full: list[float] = []
    for seq in run["per_sequence"].values():
        if method in seq and "stream" in seq[method]:
            for cpu, label in zip(seq[method]["cpu"], seq[method]["stream"], strict=True):
                (pred if label == "predicted" else full).append(cpu)
    return pred, full


def table(path: str) -> str:
    """The Markdown table of one run."""
    run = json.load(open(path))
    methods = run["methods"]
    base = methods["stream_lite"]["cpu_seconds"]
    load = run.get("load") or [float("nan")]
    lines = [f"{path}: load {min(load):.1f}-{max(load):.1f}", "",
             "| method | mean AEE | AEE / DIS medium | CPU ms/frame | CPU / stream_lite | predicted / fallbacks | "
             "CPU ms predicted frame | CPU ms full solve (n) |", "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for name, r in methods.items():
        pred, full = split_cpu(run, name)
        pm = f"{1000 * sum(pred) / len(pred):.2f}" if pred else "-"
        fm = f"{1000 * sum(full) / len(full):.2f} ({len(full)})" if full and pred else "-"
        lines.append(f"| {name} | {r['aee']:.4f} | {r.get('aee_vs_dis_medium', float('nan')):.3f} | "
                     f"{1000 * r['cpu_seconds']:.2f} | {r['cpu_seconds'] / base:.3f} | {r.get('predicted', '')} / "
                     f"{r.get('fallbacks', '')} | {pm} | {fm} |")
    return "\n".join(lines)


if __name__ == "__main__":
    print("\n\n".join(table(p) for p in sys.argv[1:]))
