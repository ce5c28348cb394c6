"""The census flows of the 8 Middlebury pairs saved (``save``) and compared (``compare``) between two trees.

    PYTHONPATH=<tree> python bench/results/census_cost/censt/flows.py save <file.npz>
    python bench/results/census_cost/censt/flows.py compare <before.npz> <after.npz>   # markdown table

FlowEstimator, numba, one thread, ``photometric=census``, each preset's own alpha; ``colour=grey`` on the luma,
``colour=channels`` on the RGB frames (bench.suite.data.read_float); flows and ``unexplained`` per preset, colour
mode and pair (as bench/results/census_cost/flows.md).
"""

from __future__ import annotations

import sys

import numpy as np

PRESETS = ("realtime", "fastest", "quality")
COLOURS = ("grey", "channels")


def save(path: str) -> None:
    from bench.common import DEFAULT_DATA
    from bench.suite.data import middlebury, read_float
    from flow_node.core.api import FlowEstimator
    from flow_node.core.config import FlowConfig
    out = {}
    samples = middlebury(False)
    for p in PRESETS:
        for c in COLOURS:
            est = FlowEstimator(FlowConfig.preset(p).replace(threads=1, photometric="census", colour=c))
            for s in samples:
                n = s.name
                f0, f1 = ((s.f0, s.f1) if c == "grey" else
                          (read_float(DEFAULT_DATA / n / f"frame1{k}.png") for k in (0, 1)))
                r = est.estimate(f0, f1)
                out[f"{p}/{c}/{n}/flow"] = r.flow
                out[f"{p}/{c}/{n}/unexplained"] = np.float64(r.unexplained)
                out[f"{p}/{c}/{n}/gt"] = s.gt
    np.savez_compressed(path, **out)


def aee(flow: np.ndarray, gt: np.ndarray) -> float:
    ok = np.all(np.isfinite(gt) & (np.abs(gt) < 1e9), axis=-1)
    return float(np.mean(np.linalg.norm(flow - gt, axis=-1)[ok]))


def compare(before: str, after: str) -> None:
    b, a = np.load(before), np.load(after)
    keys = sorted({k.rsplit("/", 1)[0] for k in b.files}, key=lambda k: (PRESETS.index(k.split("/")[0]), k))
    print("| preset / input / pair | max abs diff px | mean abs diff px | pixels > 1e-3 px | AEE before | AEE after"
          " | unexplained before | after |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    means: dict[str, list[tuple[float, float, float, float]]] = {}
    for k in keys:
        fb, fa, gt = b[k + "/flow"], a[k + "/flow"], b[k + "/gt"]
        d = np.abs(fa - fb)
        eb, ea = aee(fb, gt), aee(fa, gt)
        print(f"| {k} | {d.max():.1e} | {d.mean():.1e} | {int((d.max(-1) > 1e-3).sum())} | {eb:.4f} | {ea:.4f} | "
              f"{float(b[k + '/unexplained']):.4f} | {float(a[k + '/unexplained']):.4f} |")
        means.setdefault(k.rsplit("/", 1)[0], []).append((eb, ea, float(d.mean()), float(d.max())))
    print()
    for g, rows in means.items():
        eb, ea, dm = (float(np.mean([r[i] for r in rows])) for i in range(3))
        dx = max(r[3] for r in rows)
        print(f"- `{g}`: mean AEE {eb:.4f} -> {ea:.4f}, mean |diff| {dm:.1e} px, max {dx:.1e}")


if __name__ == "__main__":
    if sys.argv[1] == "save":
        save(sys.argv[2])
    else:
        compare(sys.argv[2], sys.argv[3])
