"""Chambolle-Pock primal-dual iteration on one linearised problem (one warp), numpy reference backend.

    y^{k+1} = prox_{sigma F*}(y^k + sigma K xbar^k)
    x^{k+1} = prox_{tau G}(x^k - tau K* y^{k+1})        x = (v, w)
    xbar^{k+1} = 2 x^{k+1} - x^k

Over-relaxed (SolveParams.relaxation rho in (0, 2), FlowConfig.pd_relaxation; He & Yuan 2012, Condat 2013): each
step's prox outputs y~, x~ are relaxed against the step's inputs, y <- y + rho (y~ - y), x <- x + rho (x~ - x),
and xbar = 2 x~ - x uses the unrelaxed x~; rho = 1 is the iteration above bit for bit (:func:`relax`).

with the prox operators and step sizes of models.py. This module is the readable reference and the test
oracle of the numba kernels; both implement :data:`LevelSolver`.

Scaling (a deliberate, tested change from the paper's literal form): we iterate on the equivalent energy
E / alpha = (1/alpha) D(v) + R(v) + (alpha1/alpha) S(w), which has the same minimisers. With images in
[0, 1] the data term's curvature |grad I|^2 is ~1e-3, so in the literal form prox_{tau G} barely moves v
and L2 data terms need thousands of iterations; weighting the data by 1/alpha instead puts the
regulariser at unit scale, where the paper's step sizes (tau, sigma) are well matched. The dual variables
are then y / alpha (the TV ball has radius 1).

The same code runs on images (v (2, H, W)) and volumes (v (3, Z, Y, X)): the operators take the number of
spatial axes from v. On volumes an optional incompressibility penalty (beta/2)|div v|^2 adds a dual block s
(models.flow_divergence; docs/engine.md, "Volumes").
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .models import (
    PROX_DATA,
    ModelSpec,
    affine_modes,
    apply_a,
    apply_a_adjoint,
    energy,
    flow_divergence,
    mass_residual,
    mass_steps,
    mode_step,
    project_dual_tv,
    prox_data_joint,
    prox_data_metric,
    prox_data_quadratic,
    prox_dual_data,
    prox_dual_incompressibility,
    prox_dual_l2,
    residual,
    step_sizes,
)
from .operators import div, grad

CHECK_EVERY = 10  # iterations between evaluations of the stopping rule
# weight s of the mass data row in the preconditioning (models.mass_steps): on the mass regime's tune seeds the
# AEE is flat for s in 2-8 (0.069-0.071 px at 10 warps; 0.091-0.095 at 5) and worse at 1 (slow data dual)
MASS_DATA_SCALE = 4.0
MODE_STEP_MAX = 0.25  # px: the largest change of the flow one affine-mode step may make (shift_slow_modes)


@dataclass
class PDState:
    """Primal and dual variables of one pyramid level (shapes in models.py); carried across warps/levels.
    ``p`` (H, W), the dual of the mass-preservation data term, is carried across the warps of a level only
    (None: start from zero)."""

    v: np.ndarray
    y: np.ndarray
    w: np.ndarray | None = None
    z: np.ndarray | None = None
    s: np.ndarray | None = None
    p: np.ndarray | None = None

    def data_dual(self) -> np.ndarray:
        """``p``, set to zeros (H, W) float32 first when missing or of another shape."""
        if self.p is None or self.p.shape != self.v.shape[1:]:
            self.p = np.zeros(self.v.shape[1:], np.float32)
        return self.p

    @classmethod
    def zeros(cls, spec: ModelSpec, shape: tuple[int, ...], incompressible: bool = False) -> PDState:
        """Zero state on a grid of ``shape`` ((H, W) or (Z, Y, X)); ``s`` only with ``incompressible``."""
        n, f = len(shape), np.float32
        return cls(
            v=np.zeros((n,) + shape, f),
            y=np.zeros((n, n) + shape, f),
            w=np.zeros((n, n) + shape, f) if spec.extended else None,
            z=np.zeros((n, n, n) + shape, f) if spec.regulariser == "tv_tv" else None,
            s=np.zeros(shape, f) if incompressible else None,
        )


@dataclass(frozen=True)
class Problem:
    """One linearised problem: rho(v) = a . v + c, and the Bregman linear term -alpha <b, v> (b may be None).

    ``q`` (5, H, W), when given, is a multi-channel data term collapsed to a quadratic form per pixel (the
    census data term, census.py); it then replaces the model's data term on (a, c). ``m`` (H, W), when given,
    makes the data term mass preservation, rho(v) = a . v + m div v + c (models.apply_a): no longer pointwise,
    it is dualised (p, models.prox_dual_data) with diagonally preconditioned steps (models.mass_steps).
    ``ab`` (2, H, W), ``cb`` (H, W), only with ``m``: a brightness-constancy term ab . v + cb beside the mass term,
    the model's data penalty on it with its weight folded in (FlowConfig.mass_brightness, models.weight_data),
    pointwise, so it stays in G (models.prox_data_metric with the per-pixel steps).
    ``g`` (H, W), when given, weights the first regulariser term per pixel, g |grad v| (edges.py): the dual ball
    of y has radius g (for the quadratic regulariser, (g/2)|grad v|^2: y / (1 + sigma / g)); None = 1."""

    a: np.ndarray
    c: np.ndarray
    b: np.ndarray | None = None
    q: np.ndarray | None = None
    m: np.ndarray | None = None
    ab: np.ndarray | None = None
    cb: np.ndarray | None = None
    g: np.ndarray | None = None

    @property
    def brightness_term(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(ab, cb) of the brightness term beside the mass term, or None."""
        return None if self.ab is None else (self.ab, self.cb)


@dataclass(frozen=True)
class SolveParams:
    spec: ModelSpec
    alpha: float
    alpha1: float
    tv_norm: str
    iterations: int
    tolerance: float
    incompressibility: float = 0.0  # beta of (beta/2)|div v|^2, absolute like alpha (volumes only)
    gamma: float = 0.0  # > 0: the joint model's data term J_gamma instead of the L1 one (models.prox_data_joint)
    relaxation: float = 1.0  # rho of the over-relaxed iteration (module docstring, :func:`relax`); 1 = plain


# A level solver updates the state in place and returns the number of iterations it ran.
LevelSolver = Callable[[Problem, PDState, SolveParams], int]


def solve_numpy(problem: Problem, state: PDState, p: SolveParams) -> int:
    """Run up to p.iterations primal-dual steps on ``problem`` from ``state`` (updated in place).

    Stops early, checked every CHECK_EVERY iterations, when the RMS change of v per iteration falls below
    p.tolerance (px); returns the number of iterations run.
    """
    spec = p.spec
    dims, incompressible = state.v.ndim - 1, p.incompressibility > 0.0
    tau, sigma = step_sizes(spec, dims, incompressible)
    tau_data = tau / p.alpha  # prox of tau * (1/alpha) D
    rel1 = p.alpha1 / p.alpha  # weight of S(w) relative to the first TV term
    rel_inc = p.incompressibility / p.alpha  # weight of the div v penalty relative to the first TV term
    prox_data = PROX_DATA[spec.data]
    if p.gamma > 0.0:
        def prox_data(vt: np.ndarray, a: np.ndarray, c: np.ndarray, t: float) -> np.ndarray:
            return prox_data_joint(vt, a, c, t, p.gamma)
    a, c, q = problem.a, problem.c, problem.q
    radius = 1.0 if problem.g is None else problem.g  # the dual ball of y: 1, or the edge weight g (H, W)
    shift = None if problem.b is None else tau * problem.b  # linear term -<b, v> of E / alpha
    mass = problem.m is not None
    if mass:  # K = [regulariser; A]: the data dual p and per-pixel steps (sigma_p, tau_v) replace prox_{tau G}
        p_data, m = state.data_dual(), problem.m
        sigma_p, tau_v = mass_steps(a, m, tau, MASS_DATA_SCALE)
    v, y, w, z, s = state.v, state.y, state.w, state.z, state.s
    if incompressible and s is None:
        s = np.zeros(v.shape[1:], np.float32)
    v_bar, w_bar = v.copy(), (None if w is None else w.copy())
    rho = p.relaxation
    for k in range(1, p.iterations + 1):
        # dual ascent: y <- prox_{sigma F*}(y + sigma K xbar) (relaxed against y with rho != 1)
        gv = grad(v_bar, dims=dims)
        ky = gv if w_bar is None else gv - w_bar
        if spec.regulariser == "l2":
            y = relax(prox_dual_l2(y + sigma * ky, sigma, radius), y, rho)
        else:
            y = relax(project_dual_tv(y + sigma * ky, radius, p.tv_norm, dims), y, rho)
        if z is not None:
            z = relax(project_dual_tv(z + sigma * grad(w_bar, dims=dims), rel1, p.tv_norm, dims), z, rho)
        if incompressible:
            s = relax(prox_dual_incompressibility(s + sigma * flow_divergence(v_bar), sigma, rel_inc), s, rho)
        if mass:
            p_data = relax(prox_dual_data(p_data + sigma_p * mass_residual(v_bar, a, m, c), sigma_p, 1.0 / p.alpha,
                                          spec.data), p_data, rho)
        # primal descent: x <- prox_{tau G}(x - tau K* y); K* of the div v block: -div of s on y's diagonal
        ys = y
        if incompressible:
            ys = y.copy()
            for d in range(dims):
                ys[d, d] += s
        if mass:  # G: the Bregman term (a gradient step with the per-pixel tau_v) and the brightness term's prox
            v_new = v + tau_v * (div(ys) - apply_a_adjoint(p_data, a, m)
                                 + (0.0 if problem.b is None else problem.b))
            if problem.ab is not None:
                v_new = prox_data_metric(v_new, problem.ab, problem.cb, tau_v, 1.0 / p.alpha, spec.data)
        else:
            vt = v + tau * div(ys)
            if shift is not None:
                vt += shift
            v_new = prox_data(vt, a, c, tau_data) if q is None else prox_data_quadratic(vt, q, tau_data)
        if w is not None:
            wt = w + tau * (y if z is None else y + div(z))
            w_new = wt / (1.0 + tau * rel1) if spec.regulariser == "tv_l2" else wt
            w_bar = 2.0 * w_new - w
            w = relax(w_new, w, rho)
        v_bar = 2.0 * v_new - v
        done = k % CHECK_EVERY == 0 and p.tolerance > 0 and _rms(v_new - v) < p.tolerance
        v = relax(v_new, v, rho)
        if done:
            break
    state.v, state.y, state.w, state.z, state.s = v, y, w, z, s
    if mass:
        state.p = p_data
        shift_slow_modes(problem, state, p)
    return k


def shift_slow_modes(problem: Problem, state: PDState, p: SolveParams) -> None:
    """A descent step of the mass problem's energy along the affine flows (models.affine_modes), run after
    its primal-dual steps in every backend. The dualised data term moves these smooth modes
    slowly: their data curvature |a|^2 is tiny next to the divergence part's |M|^2, which sets the steps.
    theta minimises the data term along them (models.mode_step; with the brightness term beside the mass term,
    both, stacked); the step is taken only if the whole energy
    (data, regulariser and the linear term -alpha <b, v>) decreases and is cut to MODE_STEP_MAX px: the energy
    is the warp's linearised one, which holds only near v0 (uncut, one step took a fine texture's flow 5 px
    off). state.v updated in place."""
    a, m, c = problem.a, problem.m, problem.c
    modes = affine_modes(state.v.shape[1:])
    phi = np.stack([apply_a(e, a, m) for e in modes])
    r = mass_residual(state.v, a, m, c)
    bc = problem.brightness_term
    if bc is not None:  # the two terms' rows stacked (the brightness term's weight is folded into ab, cb)
        phi = np.concatenate([phi, np.stack([residual(e, bc[0], 0.0) for e in modes])], axis=1)
        r = np.concatenate([r, residual(state.v, *bc)], axis=0)
    theta = mode_step(phi, r, p.spec.data)
    if not np.any(theta):
        return
    step = np.tensordot(theta, modes, axes=1)
    largest = float(np.max(np.abs(step)))
    if largest > MODE_STEP_MAX:  # a trust region: the linearisation holds within a fraction of a pixel
        step *= MODE_STEP_MAX / largest
    moved = (state.v + step).astype(np.float32)
    before, after = (energy(p.spec, v, state.w, a, c, p.alpha, p.alpha1, p.tv_norm, m=m, bc=bc, weight=problem.g)
                     - (0.0 if problem.b is None else p.alpha * float(np.sum(problem.b * v, dtype=np.float64)))
                     for v in (state.v, moved))
    if after < before:
        state.v = moved


def relax(new: np.ndarray, old: np.ndarray, rho: float) -> np.ndarray:
    """old + rho (new - old), written new + (rho - 1)(new - old) (any shape, ``new``'s dtype); rho = 1 returns
    ``new`` itself (the plain iteration bit for bit)."""
    if rho == 1.0:
        return new
    return (new + np.float32(rho - 1.0) * (new - old)).astype(new.dtype, copy=False)


def _rms(d: np.ndarray) -> float:
    return float(np.sqrt(np.mean(d * d)))
