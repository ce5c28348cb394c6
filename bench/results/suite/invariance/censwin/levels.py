"""census_radius 2 on some pyramid levels only (monkeypatch of refine.level_census; numba kernels of this branch):

    python bench/results/suite/invariance/censwin/levels.py OUT.json REGIMES [--quick]

Methods: quality / realtime census with radius 2 on the finest solved level only (``_fine2``) and on every level
but the finest (``_coarse2``). The finest solved level is the one whose width is the input's times
scale_factor ** finest_level (the estimate's input width is recorded by a wrapper of FlowEstimator.estimate)."""
from __future__ import annotations

import json
import sys
from dataclasses import replace

import flow_node.core.api as api
import flow_node.core.refine as refine
from flow_node.core.config import FlowConfig


class _state:  # noqa: N801 (the running estimate's input width and rule; one estimate at a time)
    width, rule = 0, ""
_level_census = refine.level_census
_estimate = api.FlowEstimator.estimate


def level_census(cfg, width, eps_floor=0.0):  # noqa: ANN001, ANN201
    params = _level_census(cfg.replace(census_radius=1), width, eps_floor)
    finest = width >= _state.width * cfg.scale_factor ** cfg.finest_level - 1.0
    rule = _state.rule
    two = (rule == "fine2" and finest) or (rule == "coarse2" and not finest)
    return replace(params, radius=2) if two else params


class Estimator(api.FlowEstimator):
    rule = ""

    def estimate(self, f0, f1, *args, **kwargs):  # noqa: ANN001, ANN002, ANN003, ANN201
        _state.width, _state.rule = f0.shape[1], self.rule
        return _estimate(self, f0, f1, *args, **kwargs)


def main() -> None:
    out, regimes, quick = sys.argv[1], sys.argv[2].split(","), "--quick" in sys.argv
    refine.level_census = level_census
    import bench.suite.methods as methods_mod
    from bench.suite import run_suite

    made = {}
    base = {"quality": dict(photometric="census", alpha=0.045, threads=1),
            "realtime": dict(photometric="census", threads=1)}
    for preset, kw in base.items():
        for rule in ("fine2", "coarse2"):
            made[f"{preset}_census_{rule}"] = (FlowConfig.preset(preset).replace(**kw), rule)

    class Rule(methods_mod.FlowNode):  # the suite's method for a FlowConfig, with the rule's estimator
        def __init__(self, config: FlowConfig, rule: str) -> None:
            super().__init__(config)
            est = Estimator(config)
            est.rule = rule
            self.estimator = est

    methods = {n: Rule(c, r) for n, (c, r) in made.items()}
    full = [r for r in regimes if r in ("middlebury", "bags")]
    rest = [r for r in regimes if r not in full]
    res = {"regimes": {}}
    for names, q in ((full, False), (rest, quick)):
        if names:
            part = run_suite(methods, regimes=names, split="tune", quick=q, peers=(), repeats=1, slow_repeats=1)
            res["regimes"].update(part["regimes"])
    with open(out, "w") as fh:
        json.dump(res, fh, default=str)


if __name__ == "__main__":
    main()
