"""The paper's figures as PNGs (matplotlib, Agg): Figure 1 (AE drawback), Figure 2 (per-sequence errors),
Figure 3 (colour-coded flows)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from flow_node.core.flowio import flow_to_color  # noqa: E402

from .algorithms import ALGORITHMS  # noqa: E402

COLOURS = {"l2_l2": "tab:blue", "l2_tv": "tab:red", "l2_tv_bregman": "black", "l1_tv": "tab:green",
           "l1_tv_l2": "tab:orange", "l1_tv_tv": "lightsteelblue"}


def angular_error_deg(v: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Angle (deg) between (v, 1) and (gt, 1) for arrays of 2-vectors (..., 2)."""
    num = 1.0 + np.sum(v * gt, axis=-1)
    den = np.sqrt(1.0 + np.sum(v * v, axis=-1)) * np.sqrt(1.0 + np.sum(gt * gt, axis=-1))
    return np.degrees(np.arccos(np.clip(num / den, -1.0, 1.0)))


def figure1(path: Path) -> dict[str, Any]:
    """AE of a fixed absolute (0.01 px) and a fixed relative (1 %) error against the true speed.

    The estimate is the true vector shortened (the paper's v_rel = 0.99 v_gt; v_abs shortened by 0.01 px).
    Returns a few sampled values for the report.
    """
    speed = np.linspace(0.0, 10.0, 401)[1:]
    d = np.array([1.0, 1.0]) / np.sqrt(2.0)
    gt = speed[:, None] * d
    v_abs = (speed - 0.01)[:, None] * d
    v_rel = 0.99 * gt
    ae_abs, ae_rel = angular_error_deg(v_abs, gt), angular_error_deg(v_rel, gt)
    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    ax.plot(speed, ae_abs, color="tab:blue", label="absolute error 0.01 px")
    ax.plot(speed, ae_rel, color="tab:red", label="relative error 1 %")
    ax.set_xlabel("|v_gt| (px)")
    ax.set_ylabel("angular error (deg)")
    ax.set_title("AE of the same error at different speeds")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    at = {s: int(np.argmin(np.abs(speed - s))) for s in (0.1, 1.0, 5.0)}
    return {"abs": {str(s): float(ae_abs[i]) for s, i in at.items()},
            "rel": {str(s): float(ae_rel[i]) for s, i in at.items()}}


def figure2(results: dict[str, Any], peer: dict[str, dict[str, float]], path: Path, title: str) -> None:
    """Per-sequence AEE and AE (columns) for dynamic, fixed and static weights (rows); the peer dashed."""
    seqs = list(next(iter(results.values()))["static"])
    x = np.arange(1, len(seqs) + 1)
    kinds = ("dynamic", "fixed", "static")
    fig, axes = plt.subplots(len(kinds), 2, figsize=(11, 10), sharex=True)
    for row, kind in enumerate(kinds):
        for col, metric in enumerate(("aee", "ae")):
            ax = axes[row, col]
            for alg in ALGORITHMS:
                per = results[alg.key][kind]
                ax.plot(x, [per[s][metric] for s in seqs], color=COLOURS[alg.key], label=alg.label, marker=".")
            ax.plot(x, [peer[s][metric] for s in seqs], color="grey", ls="--", label="OpenCV DualTVL1 (8-bit)")
            ax.set_title(f"{kind} parameters: {metric.upper()}" + (" (px)" if metric == "aee" else " (deg)"))
            ax.set_xticks(x, [s[:6] for s in seqs], rotation=30)
            ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def figure3(flows: dict[str, dict[str, np.ndarray]], gts: dict[str, np.ndarray], variant: str,
            path: Path) -> None:
    """Rows: ground truth and each algorithm (fixed weights); columns: the figure sequences.

    Colour scale fixed at 1 px (the protocol's largest ground-truth magnitude); unknown GT is black."""
    seqs = list(gts)
    rows = [("ground truth", gts)] + [(a.label, flows[f"{variant}/{a.key}"]) for a in ALGORITHMS]
    fig, axes = plt.subplots(len(rows), len(seqs), figsize=(3.2 * len(seqs), 2.25 * len(rows)))
    for r, (label, per) in enumerate(rows):
        for c, s in enumerate(seqs):
            ax = axes[r, c]
            ax.imshow(flow_to_color(per[s], max_flow=1.0))
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0:
                ax.set_title(s)
            if c == 0:
                ax.set_ylabel(label)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
