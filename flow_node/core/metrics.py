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
