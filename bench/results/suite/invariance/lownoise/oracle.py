"""Task lownoise (issue 25): which stage does a noisy frame 2 cost? Oracle swaps by monkeypatch, tune split only.

    python bench/results/suite/invariance/lownoise/oracle.py PRESET OUT.json [ORACLE,...] [REGIME,...]

For every pair of the tune split's sensor_noise family (bench/suite/photometric.py: frame 2 plus Gaussian noise of
sigma 3.5 / 10 grey levels, re-quantised to 8 bit) in the regimes photometric_real (Middlebury), real_exact_photometric
(real photos moved exactly) and photometric (fine textures), the pair is first solved clean (the unchanged pair: its
initial candidates and its pyramid recorded), then noisy with one stage swapped for the clean run's:

  none      nothing swapped (the noisy AEE)
  init      the initialisation's candidates (DIS on the ranked grey frames) of the clean pair
  weights   the edge weight g of the TV term and the weighted median's guide taken from the clean run's frame 0 levels
            (both read frame 0 only: frame 0 is the same image, so this differs only where frame 0's preprocessing
            follows frame 1's noise)
  data_f2   the census data term with frame 2's channels from the clean pyramid (same EPS floor as the noisy pair)
  data_all  the whole census data term of the clean pair (both frames, its EPS floors, its level contrasts): the upper
            bound of any data-term fix
  eps       only the EPS floors (and level contrasts) of the clean pair, frames noisy
  fusion    the fusion's cost planes of both frames from the clean pyramid
  alpha1.5, alpha2   the preset's census alpha x 1.5 / x 2 (more regularisation; no swap)
  all       init + weights + data_all + fusion (should give the clean AEE back)
  contrast  the empty-level rule's level contrasts of the clean pair (refine.level_contrast)
  data_f2_fine, data_f2_coarse   data_f2 on the finest solved level only / on every coarser level only

Writes per oracle per regime per pair the AEE (and the clean AEE) to OUT.json and prints a summary.
"""

from __future__ import annotations

import json
import sys
import time
from dataclasses import replace

import numpy as np

from bench.suite import metrics
from bench.suite.photometric import UNCHANGED, middlebury_photometric, synthetic_photometric
from bench.suite.realexact import real_exact_photometric
from flow_node.core import engine, refine
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig
from flow_node.core.initialise import Candidate
from flow_node.core.pyramid import Pyramid

REGIMES = {"photometric_real": middlebury_photometric, "real_exact_photometric": real_exact_photometric,
           "photometric": synthetic_photometric}
ORACLES = ("none", "init", "weights", "data_f2", "data_all", "eps", "fusion", "alpha1.5", "alpha2", "all")
FAMILY = "sensor_noise"


class State:
    mode = "plain"  # plain | record | swap
    swaps: frozenset[str] = frozenset()
    clean_candidates: list[Candidate] | None = None
    clean_pyr: Pyramid | None = None


S = State()
_initialise, _make_pyramid = engine.initialise, engine.make_pyramid
_edge, _wmedian, _census, _stacks = (refine.level_edge_weight, refine.warp_median, refine.census_problem,
                                     engine.level_stacks)


def _copy_pyr(p: Pyramid) -> Pyramid:
    def cp(xs):
        return None if xs is None else [np.array(x, copy=True) for x in xs]

    # contrasts: the same dicts, filled by the clean solve
    return replace(p, i0=cp(p.i0), i1=cp(p.i1), c0=cp(p.c0), c1=cp(p.c1))


def initialise(*a, **k):
    out = _initialise(*a, **k)
    if S.mode == "record":
        S.clean_candidates = [Candidate(c.name, c.flow.copy(), c.backward_flow(), c.far) for c in out]
    if S.mode == "swap" and "init" in S.swaps:
        return list(S.clean_candidates)
    return out


def make_pyramid(*a, **k):
    pyr = _make_pyramid(*a, **k)
    if S.mode == "record":
        S.clean_pyr = _copy_pyr(pyr)
    return pyr


def _level(shape) -> int:
    return [tuple(s) for s in S.clean_pyr.shapes].index(tuple(shape))


def level_edge_weight(i0, cfg, level=0, valid0=None, *a, **k):
    if S.mode == "swap" and "weights" in S.swaps:
        i0 = S.clean_pyr.i0[_level(i0.shape)]
    return _edge(i0, cfg, level, valid0, *a, **k)


def warp_median(v, i0, *a, **k):
    if S.mode == "swap" and "weights" in S.swaps:
        i0 = S.clean_pyr.i0[_level(i0.shape)]
    return _wmedian(v, i0, *a, **k)


def census_problem(c0, c1, cfg, backend, robust, eps_floor=0.0, finest=False, g=None, memo=None):
    if S.mode == "swap" and "fine" in S.swaps and not finest or "coarse" in S.swaps and finest:
        return _census(c0, c1, cfg, backend, robust, eps_floor, finest, g, memo)
    if S.mode == "swap" and "contrast" in S.swaps:
        memo = (*S.clean_pyr.contrasts, _level(c0.shape[1:]))
    if S.mode == "swap" and S.swaps & {"data_f2", "data_all", "eps"}:
        p, lvl = S.clean_pyr, _level(c0.shape[1:])
        if S.swaps & {"data_f2", "data_all"}:
            c1 = p.c1[lvl] if p.c1 is not None else p.i1[lvl][None]
        if "data_all" in S.swaps:
            c0 = p.c0[lvl] if p.c0 is not None else p.i0[lvl][None]
        if S.swaps & {"data_all", "eps"}:
            eps_floor = p.eps_floor(lvl, cfg.census_finest_radius if finest else 1)
            memo = (*p.contrasts, lvl)
    return _census(c0, c1, cfg, backend, robust, eps_floor, finest, g, memo)


def level_stacks(pyr, level, backend, photometric):
    if S.mode == "swap" and "fusion" in S.swaps:
        pyr = S.clean_pyr
    return _stacks(pyr, level, backend, photometric)


engine.initialise, engine.make_pyramid, engine.level_stacks = initialise, make_pyramid, level_stacks
refine.level_edge_weight, refine.warp_median, refine.census_problem = level_edge_weight, warp_median, census_problem

SWAPS = {"none": set(), "init": {"init"}, "weights": {"weights"}, "data_f2": {"data_f2"}, "data_all": {"data_all"},
         "eps": {"eps"}, "fusion": {"fusion"}, "alpha1.5": set(), "alpha2": set(),
         "all": {"init", "weights", "data_all", "fusion"}, "data_f2_fine": {"data_f2", "fine"},
         "data_f2_coarse": {"data_f2", "coarse"}, "contrast": {"contrast"}}


def main() -> None:
    preset, out = sys.argv[1], sys.argv[2]
    oracles = sys.argv[3].split(",") if len(sys.argv) > 3 and sys.argv[3] else list(ORACLES)
    regimes = sys.argv[4].split(",") if len(sys.argv) > 4 else list(REGIMES)
    cfg = FlowConfig.preset(preset)
    alpha = cfg.census_alpha or cfg.alpha
    ests = {"base": FlowEstimator(cfg)}
    for o, f in (("alpha1.5", 1.5), ("alpha2", 2.0)):
        if o in oracles:
            ests[o] = FlowEstimator(cfg.replace(census_alpha=alpha * f))
    for e in ests.values():
        e.warmup()
    res: dict = {"preset": preset, "oracles": oracles, "regimes": {}}
    t0 = time.time()
    for regime in regimes:
        rows = res["regimes"].setdefault(regime, [])
        clean = None
        for s in REGIMES[regime]("tune", False):
            if s.variant == UNCHANGED:
                clean = s
                S.mode = "record"
                flow = ests["base"].estimate(s.f0, s.f1).flow
                S.mode = "plain"
                clean_aee = metrics.score_pair(flow, s.gt, s.occluded)["aee"]
                continue
            if not s.variant.startswith(FAMILY + "/"):
                continue
            assert clean is not None and s.name.startswith(clean.name.rsplit("_", 1)[0])
            row = {"pair": s.name, "variant": s.variant, "clean": clean_aee}
            for o in oracles:
                S.mode, S.swaps = "swap", frozenset(SWAPS[o])
                flow = ests.get(o, ests["base"]).estimate(s.f0, s.f1).flow
                S.mode = "plain"
                row[o] = metrics.score_pair(flow, s.gt, s.occluded)["aee"]
            rows.append(row)
            print(f"{time.time() - t0:7.1f}s {regime} {s.name}: clean {clean_aee:.4f} "
                  + " ".join(f"{o} {row[o]:.4f}" for o in oracles), flush=True)
    summary = {}
    for regime, rows in res["regimes"].items():
        if not rows:
            continue
        c = float(np.mean([r["clean"] for r in rows]))
        summary[regime] = {"clean": c, **{o: float(np.mean([r[o] for r in rows])) for o in oracles}}
    res["summary"] = summary
    with open(out, "w") as fh:
        json.dump(res, fh, indent=1)
    for regime, m in summary.items():
        gap = m["none"] - m["clean"]
        print(f"{regime}: clean {m['clean']:.4f} noisy {m['none']:.4f} ({m['none'] / m['clean']:.2f}x) | "
              + " ".join(f"{o} {m[o]:.4f} ({100 * (m['none'] - m[o]) / gap if gap else 0:+.0f}% of gap)"
                         for o in oracles if o != "none"))


if __name__ == "__main__":
    main()
