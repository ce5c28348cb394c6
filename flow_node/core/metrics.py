"""Error measures with the Middlebury definitions (Baker et al., IJCV 2011; paper, "Error Measures")."""

from __future__ import annotations

import numpy as np

from .errors import InputError

UNKNOWN_FLOW = 1e9  # ground-truth magnitudes at or above this (or non-finite) are unknown


def valid_mask(gt: np.ndarray) -> np.ndarray:
    """Pixels whose ground truth is known: finite and |component| < 1e9. gt: (H, W, 2) -> (H, W) bool."""
    return np.isfinite(gt).all(axis=-1) & (np.abs(gt) < UNKNOWN_FLOW).all(axis=-1)


def _pair(flow: np.ndarray, gt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    if flow.shape != gt.shape or flow.ndim != 3 or flow.shape[-1] != 2:
        raise InputError(f"flow {flow.shape} and ground truth {gt.shape} must both be (H, W, 2)")
    m = valid_mask(gt)
    if not m.any():
        raise InputError("ground truth has no known pixel")
    return flow[m].astype(np.float64), gt[m].astype(np.float64)


def endpoint_error_map(flow: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Per-pixel endpoint error |flow - gt| (H, W); NaN where gt is unknown."""
    err = np.linalg.norm(flow.astype(np.float64) - gt, axis=-1)
    return np.where(valid_mask(gt), err, np.nan)


def aee(flow: np.ndarray, gt: np.ndarray) -> float:
    """Average endpoint error over known pixels (px)."""
    f, g = _pair(flow, gt)
    return float(np.mean(np.linalg.norm(f - g, axis=-1)))


def angular_error(flow: np.ndarray, gt: np.ndarray) -> float:
    """Average angle (degrees) between (u, v, 1) and (u_gt, v_gt, 1) over known pixels."""
    f, g = _pair(flow, gt)
    num = 1.0 + np.sum(f * g, axis=-1)
    den = np.sqrt(1.0 + np.sum(f * f, axis=-1)) * np.sqrt(1.0 + np.sum(g * g, axis=-1))
    return float(np.degrees(np.mean(np.arccos(np.clip(num / den, -1.0, 1.0)))))


CORRECT_PX = 3.0  # KITTI's outlier rule: an endpoint error under 3 px or 5 % of |gt| counts as correct


def confidence_auc(confidence: np.ndarray, flow: np.ndarray, gt: np.ndarray) -> float | None:
    """How well a confidence (H, W) in [0, 1] ranks the pixels of ``flow`` (H, W, 2) by their real error:
    the area under the ROC curve of "confidence predicts a correct pixel" (endpoint error below 3 px or
    5 % of |gt|, KITTI's rule), over known ground truth. 1 = every correct pixel is more confident than
    every wrong one, 0.5 = no better than chance; None when all known pixels are correct or all wrong."""
    m = valid_mask(gt)
    err = np.linalg.norm(flow[m].astype(np.float64) - gt[m], axis=-1)
    good = err < np.maximum(CORRECT_PX, 0.05 * np.linalg.norm(gt[m].astype(np.float64), axis=-1))
    n_good, n_bad = int(good.sum()), int((~good).sum())
    if n_good == 0 or n_bad == 0:
        return None
    # Mann-Whitney U with mid-ranks for ties: P(conf of a correct pixel > conf of a wrong one)
    conf = confidence[m].astype(np.float64)
    order = np.argsort(conf, kind="mergesort")
    ranks = np.empty(conf.size, np.float64)
    sorted_conf = conf[order]
    _, start, counts = np.unique(sorted_conf, return_index=True, return_counts=True)
    mid = start + (counts - 1) / 2.0 + 1.0
    ranks[order] = np.repeat(mid, counts)
    u = ranks[good].sum() - n_good * (n_good + 1) / 2.0
    return float(u / (n_good * n_bad))
