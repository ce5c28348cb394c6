"""Is the mass model's border band in its energy? The finest problem of a fine_320 pair, from the ground truth.

    python -m bench.mass_energy [--pairs 1] [--iterations 2000]   # -> bench/results/mass/energy.{json,md}

Per pair and constraint the full-size problem is linearised around the ground truth (the engine's photometric
mode and linearisation, default config) and the numpy reference solver runs ``--iterations`` primal-dual steps
from it, with the mass model's border term (solver.affine_neutral) or without (``plain``); brightness
constancy for comparison. Reported: the AEE per band of distance to the edge, and the energy's data and
regulariser parts (E = D + alpha R, without the border term's linear part) at the ground truth and at the end.
If the flow leaves the ground truth while the energy falls, the band is what the discrete energy prefers.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from flow_node.core import photometric, refine
from flow_node.core.backends import NUMPY
from flow_node.core.config import FlowConfig
from flow_node.core.models import MODEL_SPECS, energy
from flow_node.core.solver import PDState, Problem, SolveParams, affine_neutral, solve_numpy

from .mass_border import band_aee
from .suite import synthetic

OUT = Path(__file__).resolve().parent / "results" / "mass" / "energy"
VARIANTS = (("brightness", "brightness", False), ("mass plain", "mass", False), ("mass + border term", "mass", True))


def energy_parts(cfg: FlowConfig, problem: Problem, v: np.ndarray) -> tuple[float, float]:
    """(D, alpha R) of cfg's model at v (2, H, W) on ``problem``, without a linear term."""
    spec = MODEL_SPECS[cfg.model]
    total = energy(spec, v, None, problem.a, problem.c, cfg.alpha, cfg.alpha1, cfg.tv_norm, m=problem.m)
    zero_m = None if problem.m is None else np.zeros_like(problem.m)
    reg = energy(spec, v, None, np.zeros_like(problem.a), np.zeros_like(problem.c), cfg.alpha, cfg.alpha1,
                 cfg.tv_norm, m=zero_m)
    return total - reg, reg


def run(index: int, iterations: int) -> list[dict[str, object]]:
    """The report pair ``index`` of fine_320 under each variant: AEE, AEE per band, energy parts."""
    i0, i1, gt, label = synthetic._pair(synthetic.REPORT_SEED0 + index, index, (320, 240))
    q0, q1 = (synthetic.quantise(x, 8).astype(np.float32) / 255.0 for x in (i0, i1))
    v_gt = np.ascontiguousarray(gt.transpose(2, 0, 1))
    rows: list[dict[str, object]] = []
    for name, constraint, neutral in VARIANTS:
        cfg = FlowConfig() if constraint == "brightness" else FlowConfig().with_overrides(["constraint=mass"])
        s0, s1 = photometric.preprocess(q0, q1, cfg.photometric)
        problem = refine.problem_source(cfg)(s0, s1, cfg, NUMPY, True)(v_gt)
        spec = MODEL_SPECS[cfg.model]
        state = PDState.zeros(spec, v_gt.shape[1:])
        state.v = v_gt.copy()

        solve = affine_neutral(solve_numpy) if neutral else solve_numpy
        solve(problem, state, SolveParams(spec, cfg.alpha, cfg.alpha1, cfg.tv_norm, iterations, 0.0))
        err = np.hypot(*(state.v - v_gt))
        rows.append({"pair": label, "method": name, "aee": float(err.mean()), "bands": band_aee(err),
                     "energy_gt": energy_parts(cfg, problem, v_gt), "energy_end": energy_parts(cfg, problem, state.v)})
    return rows


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", default="1", help="report pair indices of fine_320 (1, 5, 9: rotations)")
    ap.add_argument("--iterations", type=int, default=2000)
    ap.add_argument("--out", type=Path, default=OUT, help="path without suffix; .json and .md are written")
    args = ap.parse_args(argv)
    rows = [r for k in args.pairs.split(",") for r in run(int(k), args.iterations)]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.with_suffix(".json").write_text(json.dumps({"iterations": args.iterations, "rows": rows}, indent=1))
    keys = list(rows[0]["bands"])  # type: ignore[arg-type]
    lines = [f"Command: `python -m bench.mass_energy --pairs {args.pairs} --iterations {args.iterations}`; from the "
             "ground truth on the finest problem linearised around it; AEE (px) by distance to the edge (px); "
             "energy D / alpha R at the ground truth and at the end", "",
             "| pair | method | AEE | " + " | ".join(keys) + " | D / αR at gt | D / αR at end |",
             "|---|---|---:|" + "---:|" * len(keys) + "---:|---:|"]
    for r in rows:
        bands: dict[str, float] = r["bands"]  # type: ignore[assignment]
        (d0, r0), (d1, r1) = r["energy_gt"], r["energy_end"]  # type: ignore[misc]
        lines.append(f"| {r['pair']} | {r['method']} | {r['aee']:.4f} | "
                     + " | ".join(f"{bands[k]:.4f}" for k in keys) + f" | {d0:.1f} / {r0:.1f} | {d1:.1f} / {r1:.1f} |")
    args.out.with_suffix(".md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
