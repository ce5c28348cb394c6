"""Contrast-restoring Bregman iterations (paper, "Bregman Iterations") on one linearised problem."""

from __future__ import annotations

from dataclasses import replace

from .census import form_residual
from .models import apply_a, residual
from .operators import div
from .solver import LevelSolver, PDState, Problem, SolveParams


def bregman(problem: Problem, state: PDState, p: SolveParams, solve: LevelSolver, n: int) -> int:
    """Run ``n`` Bregman steps from ``state`` (updated in place); returns the iterations run.

    L2 data: the shifted data term -- the residual is added back, c_{k+1} = c_k + rho(v_k) with the
    original c, which is the paper's b-update written on the data. L1 data: the original form, the
    linear term -alpha <b_k, v> in G with b_k = (K* y_k)_v / alpha = -div(y_k / alpha), the subgradient
    of R at v_k that the dual variable provides (the solver's y is already y / alpha, see solver.py).
    A quadratic (census) data term ``problem.q`` is shifted the same way for L2: its linear part g gets
    the gradient T v_k + g added (the b-update of 1/2 |A v - f|^2 written on g = -A^T f); for L1 (whose census
    term is a majoriser, census.py) the subgradient form as above, which holds for any data term. Every
    other part of the problem (the mass term ``m``) passes through unchanged; with mass, rho(v) = A v + c, and the
    brightness term beside it (``ab``, ``cb``) is shifted by its own residual for L2 (the b-update of the two terms'
    rows stacked).
    """
    total = 0
    c_shift, q_shift, cb_shift = problem.c, problem.q, problem.cb
    for _ in range(n):
        if p.spec.data == "l2" and problem.q is not None:
            q_shift = q_shift.copy()
            q_shift[3:] += form_residual(problem.q, state.v)
            step = replace(problem, q=q_shift, b=None)
        elif p.spec.data == "l2":
            rho = (residual(state.v, problem.a, problem.c) if problem.m is None
                   else apply_a(state.v, problem.a, problem.m) + problem.c)
            c_shift = c_shift + rho
            step = replace(problem, c=c_shift, b=None)
            if problem.ab is not None:  # the brightness term beside the mass term: its own residual added back
                cb_shift = cb_shift + residual(state.v, problem.ab, problem.cb)
                step = replace(step, cb=cb_shift)
        else:
            step = replace(problem, b=-div(state.y))
        total += solve(step, state, p)
    return total
