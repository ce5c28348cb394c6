"""Contrast-restoring Bregman iterations (paper, "Bregman Iterations") on one linearised problem."""

from __future__ import annotations

from .models import residual
from .operators import div
from .solver import LevelSolver, PDState, Problem, SolveParams


def bregman(problem: Problem, state: PDState, p: SolveParams, solve: LevelSolver, n: int) -> int:
    """Run ``n`` Bregman steps from ``state`` (updated in place); returns the iterations run.

    L2 data: the shifted data term -- the residual is added back, c_{k+1} = c_k + rho(v_k) with the
    original c, which is the paper's b-update written on the data. L1 data: the original form, the
    linear term -alpha <b_k, v> in G with b_k = (K* y_k)_v / alpha = -div(y_k / alpha), the subgradient
    of R at v_k that the dual variable provides (the solver's y is already y / alpha, see solver.py).
    """
    total = 0
    c_shift = problem.c
    for _ in range(n):
        if p.spec.data == "l2":
            c_shift = c_shift + residual(state.v, problem.a, problem.c)
            step = Problem(problem.a, c_shift)
        else:
            step = Problem(problem.a, problem.c, -div(state.y))
        total += solve(step, state, p)
    return total
