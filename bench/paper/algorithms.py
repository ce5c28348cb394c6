"""The six algorithms of the paper's Table 1, their static parameters mapped to ours, and the dynamic grid.

The mapping (the paper's central difference omits our 1/2, so its residual is ours times s = 2: L1 data
weights / 2, L2 data weights / 4), the reading of the alpha_2 column (alpha_1 of the extended models, the
Bregman iterations of L2-TV Bregman) and the static / fixed / dynamic weights: REPORT.md, "Settings and the
parameter mapping" (written by report.py). The table's rows "L2-TV/L2" and "L2-TV/TV" are the L1 extended
models (the text and Figure 2 have only L1 extended models). DYNAMIC_FACTORS is wide on the small side: the
L2 data term's weight scales with the squared image contrast, so the paper's L2 weights need not transfer."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from flow_node.core.config import FlowConfig

# Solver settings shared by all algorithms on this protocol (flows <= 1 px). See REPORT.md for the search.
# A short pyramid (4 levels x 0.5) speeds up convergence even for 1-px flows; no median filter (it erodes
# the fine motion detail that dominates AEE at this scale).
BASE: dict[str, Any] = dict(levels=4, scale_factor=0.5, warps=3, iterations=50, median_filter=0,
                            gradient_scheme="central", tolerance=0.0, tv_norm="isotropic")

DYNAMIC_FACTORS = (1 / 1024, 1 / 256, 1 / 64, 1 / 16, 1 / 8, 1 / 4, 1 / 2, 1.0, 2.0, 4.0)


@dataclass(frozen=True)
class Algorithm:
    """One row of Table 1: the paper's static weights and our config for them."""

    key: str
    label: str
    model: str
    alpha_paper: float
    alpha2_paper: float | None = None
    bregman: int = 0
    iterations: int | None = None  # primal-dual iterations per warp when not BASE's

    @property
    def data_scale(self) -> float:
        """Factor dividing the paper's weights: s for the L1 data term, s^2 for the L2 one (s = 2)."""
        return 2.0 if self.model.startswith("l1") else 4.0

    def config(self, factor: float = 1.0, **extra: Any) -> FlowConfig:
        """Our config for this algorithm with the static weights times ``factor`` (and ``extra`` overrides)."""
        kw: dict[str, Any] = dict(BASE, model=self.model, alpha=factor * self.alpha_paper / self.data_scale,
                                  bregman_iterations=self.bregman)
        if self.iterations is not None:
            kw["iterations"] = self.iterations
        if self.model in ("l1_tv_l2", "l1_tv_tv"):
            kw["alpha1"] = factor * float(self.alpha2_paper) / self.data_scale
        kw.update(extra)
        return FlowConfig(**kw)


# Primal-dual iterations per warp: the smallest budget after which 4x more changes the static mean AEE (clean
# and noisy, factor 1) by less than ~10 %. Budget study (bench/results/paper/budget.json, 2026-12-01; a one-off,
# retired: `git show 2cc837f:bench/paper/budget.py`), mean AEE clean / noisy with the static weights:
#   L2-L2          50: 0.161 / 0.161    200: 0.098 / 0.099    1000: 0.0735 / 0.0737   4000: 0.0672 / 0.0676
#   L2-TV          50: 0.0614 / 0.0615  200: 0.0656 / 0.0657  1000: 0.0693 / 0.0693   (converged at 50)
#   L2-TV Bregman  50: 0.0626 / 0.0628  200: 0.0547 / 0.0549  1000: 0.0559 / 0.0559
#   L1-TV          50: 0.0246 / 0.0365  200: 0.0240 / 0.0352
#   L1-TV/L2       50: 0.0262 / 0.0390  200: 0.0241 / 0.0349   800: 0.0243 / 0.0351
#   L1-TV/TV       50: 0.0359 / 0.0574  150: 0.0291 / 0.0448   300: 0.0278 / 0.0408   1200: 0.0261 / 0.0365
# L1-TV/TV at 300 is on the line (noisy 300 -> 1200: -10.5 %); it stays at 300 for the run time of make paper.
# The slow ones are slow for a reason: the L2-L2 minimiser is a Horn-Schunck field whose smoothing reaches
# across the image (diffusion, ~sqrt(iterations) px per level), and L1-TV/TV has smaller steps (tau 1/5,
# sigma 1/3) and a second field w coupled to v only through grad v - w. With 50 iterations L2-L2 stopped far
# short of its minimiser, which had looked like "the paper's L2-L2 weight is 256x too large" (REPORT.md).
ALGORITHMS: tuple[Algorithm, ...] = (
    Algorithm("l2_l2", "L2-L2", "l2_l2", 0.15, iterations=1000),
    Algorithm("l2_tv", "L2-TV", "l2_tv", 0.002),
    Algorithm("l2_tv_bregman", "L2-TV Bregman", "l2_tv", 0.02, 10, bregman=10, iterations=200),
    Algorithm("l1_tv", "L1-TV", "l1_tv", 0.1),
    Algorithm("l1_tv_l2", "L1-TV/L2", "l1_tv_l2", 0.1, 50, iterations=200),
    Algorithm("l1_tv_tv", "L1-TV/TV", "l1_tv_tv", 0.1, 1, iterations=300),
)

# The paper's averaged ranks (Table 1): static AEE, static AE, dynamic AEE, dynamic AE.
PAPER_RANKS: dict[str, tuple[float, float, float, float]] = {
    "l2_l2": (1.319, 1.333, 1.360, 1.367),
    "l2_tv": (1.250, 1.266, 1.200, 1.194),
    "l2_tv_bregman": (1.345, 1.286, 1.200, 1.171),
    "l1_tv": (1.135, 1.137, 1.213, 1.212),
    "l1_tv_l2": (1.136, 1.133, 1.215, 1.211),
    "l1_tv_tv": (1.237, 1.205, 1.341, 1.315),
}

# Table 2 of the paper: L1-TV on Dimetrodon, alpha = 0.05 (paper units); AE there is in radians.
TABLE2_ALPHA_PAPER = 0.05
PAPER_TABLE2: dict[str, tuple[float, float]] = {
    "forward": (0.0515, 0.0326), "central": (0.0352, 0.0207), "interpolated": (0.0221, 0.0131)}
