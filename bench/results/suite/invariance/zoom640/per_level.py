"""Diagnosis only (task zoom640): per pyramid level AEE of realtime census on the fine 640x480 tune pairs.

    PYTHONPATH=$PWD python bench/results/suite/invariance/zoom640/per_level.py [key=value ...]
    ZOOM_SEEDS=14,26 ... per_level.py   # extra tune seeds (index = seed) instead of the regime's 8
    PRESET=quality ... per_level.py     # another preset (default realtime)

Wraps refine.solve_level to record the flow after each level and compares it with the ground truth resampled
to that level (vectors scaled by the level's width ratio), in the level's pixels and in full-size pixels.
"""

from __future__ import annotations

import os
import sys
from dataclasses import replace

import numpy as np

from bench.suite.data import Sample
from bench.suite.synthetic import _pair, fine, quantise
from flow_node.core import refine
from flow_node.core.api import estimate_flow
from flow_node.core.config import FlowConfig
from flow_node.core.pyramid import resize_flow

records: list[tuple[int, tuple[int, int], np.ndarray]] = []
_orig = refine.solve_level


def _spy(pyr, level, cfg, backend, state, on_finest, *args, **kw):  # type: ignore[no-untyped-def]
    out = _orig(pyr, level, cfg, backend, state, on_finest, *args, **kw)
    records.append((level, pyr.shapes[level], state.v.copy()))
    return out


refine.solve_level = _spy
extra = dict(kv.split("=") for kv in sys.argv[1:])
base = FlowConfig()
cfg = replace(FlowConfig.preset(os.environ.get("PRESET", "realtime")), photometric="census",
              **{k: type(getattr(base, k))(v) for k, v in extra.items()})
SEEDS = [int(x) for x in os.environ.get("ZOOM_SEEDS", "").split(",") if x]  # tune seeds (< 1000), index = seed


def samples():  # type: ignore[no-untyped-def]
    if not SEEDS:
        yield from fine("tune", False, (640, 480))
    for k in SEEDS:
        i0, i1, gt, label = _pair(k, k, (640, 480))
        yield Sample(f"s{k}_{label}", quantise(i0, 8), quantise(i1, 8), gt, 8, label.split("/")[0])


for s in samples():
    records.clear()
    flow = estimate_flow(s.f0, s.f1, cfg)
    gt = s.gt
    fl = np.asarray(flow.flow if hasattr(flow, "flow") else flow)
    full = float(np.mean(np.hypot(*(fl - gt).transpose(2, 0, 1))))
    row = []
    for level, shape, v in records:
        up = resize_flow(v, gt.shape[:2])  # full-size px
        row.append(f"L{level}({shape[1]}px) {float(np.mean(np.hypot(*(up - gt.transpose(2, 0, 1))))):.3f}")
    print(f"{s.name:22s} final {full:.4f} | " + " ".join(row), flush=True)
