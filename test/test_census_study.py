"""bench/census_study.py: the census + grey variant adds exactly the grey-value data term's quadratic form."""

from __future__ import annotations

import numpy as np

from bench.census_study import Variant, add_grey, grey_weight_map
from flow_node.core.census import CENSUS, form_residual
from flow_node.core.solver import Problem


def test_added_grey_form_is_the_weighted_grey_data_term() -> None:
    rng = np.random.default_rng(3)
    h, w = 9, 11
    a = rng.standard_normal((2, h, w)).astype(np.float32)
    c = rng.standard_normal((h, w)).astype(np.float32)
    q = rng.standard_normal((5, h, w)).astype(np.float32)
    v0, v = (rng.standard_normal((2, h, w)).astype(np.float32) for _ in range(2))
    lam, delta = 0.7, 0.05
    rho = a[0] * v[0] + a[1] * v[1] + c
    # L2: gradient of the form is the census one plus lam * rho * a
    l2 = add_grey(Problem(a, c, q=q), v0, lam, delta, robust=False)
    assert np.allclose(form_residual(l2.q, v), form_residual(q, v) + lam * rho * a, atol=1e-4)
    # L1 (IRLS): the grey part is weighted by 1 / sqrt(rho(v0)^2 + delta^2)
    wk = lam / np.sqrt((a[0] * v0[0] + a[1] * v0[1] + c) ** 2 + delta**2)
    l1 = add_grey(Problem(a, c, q=q), v0, lam, delta, robust=True)
    assert np.allclose(form_residual(l1.q, v), form_residual(q, v) + wk * rho * a, rtol=1e-4, atol=1e-3)


def test_gate_keeps_the_grey_term_off_textured_pixels() -> None:
    img = np.zeros((8, 8), np.float32)
    img[:, 4:] = 1.0  # an edge: large neighbour differences next to it, none far from it
    lam = grey_weight_map(img, Variant(grey_weight=2.0, grey_gate=2.0))
    assert isinstance(lam, np.ndarray)
    assert lam[0, 0] == 2.0 and lam[0, 3] < 0.01 * 2.0
    assert grey_weight_map(img, Variant(grey_weight=2.0)) == 2.0
    assert CENSUS.eps > 0
