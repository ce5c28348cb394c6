"""Study of census data-term variants that are not in the engine (issue 25: can census become the default?).

    python -m bench.census_study --regimes middlebury,fine_320,bags --split report --name report_realtime \\
        --method normalise=realtime --method census=realtime,photometric=census \\
        --method grey1=realtime,photometric=census,grey_weight=1,grey_delta=0.05

Each ``--method NAME=BASE[,key=value...]`` is a preset with FlowConfig overrides plus these study keys:

- ``grey_weight`` (lambda, default 0) and ``grey_delta`` (default 0.01): the census quadratic form plus
  lambda times the grey-value data term of the same warp (rho = a . v + c on the census mode's per-frame
  normalised pair) as a quadratic form of v: w a a^T and w c a with w = 1 (L2 models) or the IRLS weight
  1 / sqrt(rho(v0)^2 + grey_delta^2) (L1 models), the same majoriser the census term uses;
- ``grey_gate`` (default 0 = off): lambda per pixel times 1 / (1 + s^2 / (grey_gate * EPS)^2), s the RMS
  of frame 0's neighbour differences on the level (census.py), so the grey term only acts where the census
  signature is EPS-dominated (flat areas);
- ``coarse_grey_width`` (default 0 = off): levels narrower than this (px) use the grey-value data term alone;
- ``coarse_eps`` and ``coarse_eps_width`` (default 0 = off): the census term with EPS = ``coarse_eps`` on
  levels narrower than ``coarse_eps_width`` px (invariant still: EPS only enters the signature);
- ``antialias_steps`` (default -1 = the engine's): anti-alias at most this many pyramid steps (the finest
  ones; pyramid.build_pyramid). The census mode anti-aliases every step (docs/engine.md).

The variants wrap ``refine.census_problem`` and ``pyramid.build_pyramid`` for the run of their method (a
study tool: the engine is not changed). Writes bench/results/census_study/NAME.{json,md}; the numbers are
in docs/engine.md, "The census data term".
"""

from __future__ import annotations

import argparse
import shlex
import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from flow_node.core import pyramid, refine
from flow_node.core.census import CENSUS, OFFSETS, CensusParams, shifted
from flow_node.core.config import FlowConfig
from flow_node.core.solver import Problem

from .common import REPO, machine, write_json
from .suite.methods import FlowNode
from .suite.runner import run_suite

RESULTS = REPO / "bench" / "results" / "census_study"
ORIGINAL = refine.census_problem
ORIGINAL_PYRAMID = pyramid.build_pyramid


@dataclass(frozen=True)
class Variant:
    """The study keys of one method (module doc)."""

    grey_weight: float = 0.0
    grey_delta: float = 0.01
    grey_gate: float = 0.0
    coarse_grey_width: int = 0
    coarse_eps: float = 0.0
    coarse_eps_width: int = 0
    antialias_steps: int = -1


ACTIVE: list[Variant] = [Variant()]  # the variant of the method being run (one at a time)


def grey_weight_map(i0: np.ndarray, v: Variant) -> np.ndarray | float:
    """lambda per pixel (H, W) for ``grey_gate`` > 0, else the constant lambda."""
    if v.grey_gate <= 0:
        return v.grey_weight
    s2 = np.mean([(shifted(i0, dy, dx) - i0) ** 2 for dy, dx in OFFSETS], axis=0)
    return v.grey_weight / (1.0 + s2 / (v.grey_gate * CENSUS.eps) ** 2)


def add_grey(problem: Problem, v0: np.ndarray, lam: np.ndarray | float, delta: float, robust: bool) -> Problem:
    """The census problem's form plus lam times the grey-value term on (a, c) around v0 (module doc)."""
    a, c, q = problem.a, problem.c, problem.q.copy()
    r0 = a[0] * v0[0] + a[1] * v0[1] + c
    w = lam / np.sqrt(r0 * r0 + delta * delta) if robust else lam + np.zeros_like(c)
    q += np.stack([w * a[0] * a[0], w * a[0] * a[1], w * a[1] * a[1], w * c * a[0], w * c * a[1]])
    return Problem(a, c, q=q.astype(np.float32))


def census_with(i0: np.ndarray, i1: np.ndarray, cfg: FlowConfig, backend: Any, robust: bool,
                params: CensusParams) -> Callable[[np.ndarray], Problem]:
    """refine.census_problem with other census constants ``params``."""
    grey = refine.grey_problem(i0, i1, cfg, backend, robust)
    f0, g0 = backend.signature(i0, params)

    def around(v0: np.ndarray) -> Problem:
        lin = grey(v0)
        return Problem(lin.a, lin.c, q=backend.census_form(i0, i1, f0, g0, lin.a, lin.c, v0, robust, params))

    return around


def studied_problem(i0: np.ndarray, i1: np.ndarray, cfg: FlowConfig, backend: Any, robust: bool
                    ) -> Callable[[np.ndarray], Problem]:
    """refine.census_problem with the active variant."""
    v = ACTIVE[0]
    if i0.shape[1] < v.coarse_grey_width:
        return refine.grey_problem(i0, i1, cfg, backend, robust)
    if i0.shape[1] < v.coarse_eps_width:
        census = census_with(i0, i1, cfg, backend, robust, CensusParams(eps=v.coarse_eps))
    else:
        census = ORIGINAL(i0, i1, cfg, backend, robust)
    if v.grey_weight <= 0:
        return census
    lam = grey_weight_map(i0, v)
    return lambda v0: add_grey(census(v0), v0, lam, v.grey_delta, robust)


def studied_pyramid(img: np.ndarray, shapes: list[tuple[int, int]], scale: float, antialias_levels: int = 0
                    ) -> list[np.ndarray]:
    """pyramid.build_pyramid with at most the active variant's ``antialias_steps`` anti-aliased steps."""
    steps = ACTIVE[0].antialias_steps
    return ORIGINAL_PYRAMID(img, shapes, scale, antialias_levels if steps < 0 else min(steps, antialias_levels))


class StudiedNode(FlowNode):
    """flow_node with one config and one variant (set around each call)."""

    def __init__(self, config: FlowConfig, variant: Variant) -> None:
        self.variant = variant
        ACTIVE[0] = variant
        super().__init__(config)

    def run(self, prepared: Any) -> Any:
        ACTIVE[0] = self.variant
        return super().run(prepared)


def parse_method(spec: str) -> tuple[str, StudiedNode]:
    """NAME=BASE[,key=value...] -> (name, method)."""
    name, rest = spec.split("=", 1)
    base, *pairs = rest.split(",")
    overrides: dict[str, Any] = {}
    study: dict[str, Any] = {}
    for pair in pairs:
        key, value = pair.split("=", 1)
        if key in Variant.__dataclass_fields__:
            study[key] = type(getattr(Variant(), key))(float(value))
        else:
            overrides[key] = type(getattr(FlowConfig(), key))(value)
    return name, StudiedNode(FlowConfig.preset(base).replace(**overrides), Variant(**study))


def table(res: dict[str, Any]) -> list[str]:
    """Markdown rows: regime, method, mean AEE, seconds."""
    rows = ["| regime | method | mean AEE | s/pair |", "|---|---|---:|---:|"]
    for regime, r in res["regimes"].items():
        for method, m in r["methods"].items():
            rows.append(f"| {regime} | {method} | {m['aee']:.4f} | {m['seconds']:.3f} |")
    return rows


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--regimes", required=True)
    ap.add_argument("--split", default="report")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--name", required=True, help="result file stem under bench/results/census_study/")
    ap.add_argument("--method", action="append", required=True)
    args = ap.parse_args(argv)
    refine.census_problem = studied_problem
    pyramid.build_pyramid = studied_pyramid
    methods = dict(parse_method(m) for m in args.method)
    res = run_suite(methods, regimes=args.regimes.split(","), split=args.split, quick=args.quick, peers=())
    command = "python -m bench.census_study " + shlex.join(sys.argv[1:] if argv is None else argv)
    res["command"] = command
    res["machine"] = machine()
    write_json(RESULTS / f"{args.name}.json", res)
    md = [f"# census study: {args.name}", "", f"`{command}` (machine loaded: 2 shared cores)", "", *table(res)]
    (RESULTS / f"{args.name}.md").write_text("\n".join(md) + "\n")
    print("\n".join(md))


if __name__ == "__main__":
    main()
