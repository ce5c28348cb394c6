"""One-off diagnosis (issue 25, task blob): per-level flow error of a census preset on the synthetic photometric
pairs (bench.suite.photometric's 320x240 scenes, 8 bit), numba backend. Usage:
``python diag.py 'SEED:INDEX:LABEL,...' PRESET 'k=v k=v;k=v;...' [MAPS_DIR]`` (LABEL 'unchanged' or a
photometric.FAMILIES label such as 'illumination/blob'; the suite's pair of seed s has INDEX s % 1000; one line per
pair and override set, photometric=census always). Prints per solved level the AEE (level px) against the ground
truth resampled to the level (vectors scaled), and the final AEE; with MAPS_DIR saves each level's error map."""
from __future__ import annotations

import sys

import numpy as np

from bench.suite import photometric as ph
from bench.suite import synthetic
from bench.suite.synthetic import quantise
from flow_node.bag.scenes import render_grey_pair
from flow_node.core import refine
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig
from flow_node.core.pyramid import resize_flow


def run(seed: int, index: int, label: str, preset: str, sets: list[str], maps: str | None) -> str:
    """Per-level AEE of one pair and config (module doc)."""
    scene, name = synthetic.scene_for(index, seed, ph.SIZE, span=ph.SPAN)
    i0, i1, gt = render_grey_pair(scene)
    gt = gt.astype(np.float32)
    if label != "unchanged":
        v = next(v for f in ph.FAMILIES.values() for v in f if v.label == label)
        i1 = v(i1, seed)
    f0, f1 = quantise(i0, 8), quantise(i1, 8)
    cfg = FlowConfig.preset(preset).with_overrides(["photometric=census"] + sets)
    levels: list[tuple[int, np.ndarray]] = []
    orig = refine.solve_level

    def spy(pyr, level, *a, **k):  # type: ignore[no-untyped-def]
        out = orig(pyr, level, *a, **k)
        levels.append((level, a[2].v.copy()))
        return out

    refine.solve_level = spy
    try:
        res = FlowEstimator(cfg).estimate(f0, f1)
    finally:
        refine.solve_level = orig
    g = np.ascontiguousarray(np.moveaxis(gt, -1, 0))
    row = []
    tag = f"{seed}_{label.replace('/', '_').replace(' ', '_')}_{preset}{'_' + '_'.join(sets) if sets else ''}"
    for level, v in levels:
        err = np.hypot(*(v - resize_flow(g, v.shape[1:])))
        row.append(f"L{level} {err.mean():.3f}")
        if maps:
            np.save(f"{maps}/err_{tag}_L{level}.npy", err)
    e = np.hypot(*(res.flow - gt).transpose(2, 0, 1)).mean()
    return f"s{seed} {name} {label} {preset} [{' '.join(sets)}] | " + " | ".join(row) + f" | final {e:.3f}"


# usage: diag.py 'SEED:INDEX:LABEL,...' 'PRESET' 'k=v k=v;k=v;...' [maps dir]
if __name__ == "__main__":
    pairs = [p.split(":", 2) for p in sys.argv[1].split(",")]
    preset = sys.argv[2]
    variants = [s.split() for s in (sys.argv[3].split(";") if len(sys.argv) > 3 else [""])]
    out = sys.argv[4] if len(sys.argv) > 4 else None
    for sets in variants:
        for seed, index, label in pairs:
            print(run(int(seed), int(index), label, preset, sets, out), flush=True)
