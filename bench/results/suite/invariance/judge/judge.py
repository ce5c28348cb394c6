"""The grey-value judge against census signatures on the same flows (docs/engine.md, "The judge"; summary.md).

PYTHONPATH=. python bench/results/suite/invariance/judge/judge.py REGIMES PRESETS [--split report]
prints, per regime and preset, how many pairs each figure puts on the wrong side of UNRELIABLE: unchanged and
handled pairs (within HANDLED x the unchanged pair's AEE) at or above it, wrong ones (WRONG x and WRONG_PX more)
below it; and for regimes without families the range of each figure. The grey figure is written out here (the
engine's before 2026-12-06: |I1(x + flow) - I0(x)| > 0.05 on the normalised pair); flows are the same either way.
"""

from __future__ import annotations

import argparse
from collections import Counter

import numpy as np

from bench.suite.photometric import UNCHANGED, UNCHANGED_RGB
from bench.suite.regimes import REGIMES
from bench.suite.report import COLOUR, misread, pair_kind
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig
from flow_node.core.metrics import aee
from flow_node.core.numba_judge import reliability_numba
from flow_node.core.photometric import UNRELIABLE, reliability_stride
from flow_node.core.warping import sample_coefficients


def grey_figure(i0: np.ndarray, i1: np.ndarray, flow: np.ndarray) -> float:
    h, w = i0.shape
    s = reliability_stride(h, w)
    mx = np.arange(0, w, s, dtype=np.float32)[None, :] + flow[::s, ::s, 0]
    my = np.arange(0, h, s, dtype=np.float32)[:, None] + flow[::s, ::s, 1]
    inside = (mx >= 0) & (mx <= w - 1) & (my >= 0) & (my <= h - 1)
    return float(np.mean(np.abs(sample_coefficients(i1, mx, my, "keys") - i0[::s, ::s])[inside] > 0.05))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("regimes")
    ap.add_argument("presets")
    ap.add_argument("--split", default="report")
    args = ap.parse_args()
    for reg in args.regimes.split(","):
        for preset in args.presets.split(","):
            est = FlowEstimator(FlowConfig.preset(preset))
            rows, base = [], {}
            for s in REGIMES[reg].build(args.split, False):
                if s.variant in (UNCHANGED, UNCHANGED_RGB):
                    base[s.variant] = s.name
                ref = base.get(UNCHANGED_RGB if s.variant.split("/")[0] in COLOUR else UNCHANGED)
                r = est.estimate(s.f0, s.f1)
                rows.append((s.name, ref, aee(r.flow, s.gt), grey_figure(*r.frames, r.flow),
                             reliability_numba(*r.frames, r.flow)))
            if not base:  # no families: the figures' ranges and how many pairs read above the level
                g, c = np.array([q[3] for q in rows]), np.array([q[4] for q in rows])
                print(f"{reg} {preset}: {len(rows)} pairs, AEE {np.mean([q[2] for q in rows]):.3f}; grey "
                      f"{g.min():.3f}-{g.max():.3f} ({(g >= UNRELIABLE).sum()} above), census {c.min():.3f}-"
                      f"{c.max():.3f} ({(c >= UNRELIABLE).sum()} above)", flush=True)
                continue
            aees = {q[0]: q[2] for q in rows}
            n, off = Counter(), Counter()
            for name, ref, a, g, c in rows:
                kind = pair_kind(a, aees[ref], name == ref)
                if kind:
                    n[kind] += 1
                    for judge, u in (("grey", g), ("census", c)):
                        off[kind, judge] += misread(kind, u)
            print(f"{reg} {preset}: " + "; ".join(f"{k} {n[k]}: grey {off[k, 'grey']}, census {off[k, 'census']}"
                                                 for k in ("unchanged", "handled", "wrong")), flush=True)


if __name__ == "__main__":
    main()
