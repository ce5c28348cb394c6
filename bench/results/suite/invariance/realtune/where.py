"""Where realtime's / fastest's error lies on real_exact (task realtune): occluded, boundary band, interior.

    PYTHONPATH=$PWD .venv-bench/bin/python bench/results/suite/invariance/realtune/where.py \
        --split tune realtime fastest 'rt_a=realtime,census_alpha=0.12'

Per method (NAME=BASE[,key=value...] as bench.suite --method, or a preset name) the mean over the split's
real_exact pairs of the AEE over all known pixels, the occluded ones, a band of non-occluded pixels within 4 px of
a ground-truth motion boundary, and the rest (interior).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from scipy import ndimage

from bench.suite.methods import FlowNode, parse_method
from bench.suite.realexact import real_exact


def regions(gt: np.ndarray, occluded: np.ndarray) -> dict[str, np.ndarray]:
    """Masks (H, W) bool of the known pixels: all, occluded, boundary band (4 px), interior."""
    known = np.all(np.abs(gt) < 1e9, axis=2)
    g = np.where(known[..., None], gt, 0.0)
    edge = np.zeros(known.shape, bool)
    for ax in (0, 1):
        d = np.abs(np.diff(g, axis=ax)).sum(axis=2) > 0.1
        sl = [slice(None)] * 2
        sl[ax] = slice(0, -1)
        edge[tuple(sl)] |= d
    edge |= ~known
    band = ndimage.binary_dilation(edge, iterations=4)
    occ = occluded & known
    return {"all": known, "occ": occ, "band": band & known & ~occ, "interior": known & ~band & ~occ}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--split", default="tune")
    ap.add_argument("methods", nargs="+")
    a = ap.parse_args()
    samples = list(real_exact(a.split, False))
    print("| method | all | occ | band | interior | occ share | band share | per pair (all) |")
    print("|---|---|---|---|---|---|---|---|")
    for spec in a.methods:
        name, cfg = parse_method(spec if "=" in spec else f"{spec}={spec}")
        node = FlowNode(cfg)
        sums: dict[str, list[float]] = {k: [] for k in ("all", "occ", "band", "interior")}
        shares: dict[str, list[float]] = {"occ": [], "band": []}
        pp = []
        for s in samples:
            flow = np.asarray(node.run(node.prepare(s))[0], np.float32)
            err = np.linalg.norm(flow - np.where(np.abs(s.gt) < 1e9, s.gt, 0), axis=2)
            m = regions(s.gt, s.occluded)
            tot = err[m["all"]].sum()
            for k in sums:
                sums[k].append(float(err[m[k]].mean()) if m[k].any() else 0.0)
            for k in shares:
                shares[k].append(float(err[m[k]].sum() / tot))
            pp.append(sums["all"][-1])
        print(f"| {name} | {np.mean(sums['all']):.4f} | {np.mean(sums['occ']):.3f} | {np.mean(sums['band']):.3f} | "
              f"{np.mean(sums['interior']):.4f} | {np.mean(shares['occ']):.2f} | {np.mean(shares['band']):.2f} | "
              + " ".join(f"{v:.3f}" for v in pp) + " |", flush=True)


if __name__ == "__main__":
    sys.exit(main())
