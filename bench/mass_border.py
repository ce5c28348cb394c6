"""Where the mass model's error lies on fine_320's divergence-free pairs: AEE by distance to the border.

    python -m bench.mass_border [--pairs 0,1] [--set key=value ...]   # -> bench/results/mass/border.{json,md}

Per report pair (index 0 = shift, 1 = rotation of synthetic.fine), brightness (FlowConfig()) and mass
(``constraint=mass`` plus the ``--set`` overrides) run on the same frames; the AEE is given per band of
distance d to the nearest image edge (px). docs/engine.md, "Mass preservation", reads these numbers.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig

from .common import md_table, run_record, write_result
from .suite import synthetic

BANDS = ((0, 2), (2, 5), (5, 10), (10, 20), (20, 40), (40, 10**6))  # [lo, hi) px from the nearest edge
OUT = Path(__file__).resolve().parent / "results" / "mass" / "border"


def band_aee(err: np.ndarray) -> dict[str, float]:
    """Mean of err (H, W) per band of distance to the nearest edge; key 'lo-hi' (the last 'lo+')."""
    h, w = err.shape
    yy, xx = np.mgrid[:h, :w]
    d = np.minimum(np.minimum(yy, h - 1 - yy), np.minimum(xx, w - 1 - xx))
    return {(f"{lo}+" if hi >= 10**6 else f"{lo}-{hi}"): float(err[(d >= lo) & (d < hi)].mean()) for lo, hi in BANDS}


def measure(index: int, configs: dict[str, FlowConfig]) -> list[dict[str, Any]]:
    """One report pair of fine_320 (index into the motion cycle) under each config: AEE and AEE per band."""
    i0, i1, gt, label = synthetic._pair(synthetic.REPORT_SEED0 + index, index, (320, 240))
    q0, q1 = synthetic.quantise(i0, 8), synthetic.quantise(i1, 8)
    rows: list[dict[str, Any]] = []
    for name, cfg in configs.items():
        flow = FlowEstimator(cfg).estimate(q0, q1).flow
        err = np.hypot(flow[..., 0] - gt[..., 0], flow[..., 1] - gt[..., 1])
        rows.append({"pair": label, "method": name, "aee": float(err.mean()), "bands": band_aee(err)})
    return rows


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", default="0,1", help="report pair indices (0 shift, 1 rotation, 2 zoom, 3 affine)")
    ap.add_argument("--set", action="append", default=[], help="key=value override of the mass method")
    ap.add_argument("--out", type=Path, default=OUT, help="path without suffix; .json and .md are written")
    args = ap.parse_args(argv)
    configs = {"brightness": FlowConfig(), "mass": FlowConfig().with_overrides(["constraint=mass", *args.set])}
    rows = [r for k in args.pairs.split(",") for r in measure(int(k), configs)]
    keys = list(rows[0]["bands"])
    table = md_table(["pair", "method", "AEE", *keys], ([r["pair"], r["method"], f"{r['aee']:.4f}",
                                                         *(f"{r['bands'][k]:.4f}" for k in keys)] for r in rows), True)
    write_result(args.out, {"overrides": args.set, "rows": rows}, "\n".join(
        [f"Command: `{run_record('bench.mass_border', argv)['command']}`; AEE (px) by distance to the nearest "
         "edge (px)", "", *table]) + "\n")


if __name__ == "__main__":
    main()
