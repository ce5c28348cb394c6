"""Scores: per pair (AEE, AE, and for a method that returns a confidence, its sparsification AUSE,
docs/suite.md "Confidence"), per regime (means, per-variant means, time ratios against DIS in the same run)."""

from __future__ import annotations

from typing import Any

import numpy as np

from flow_node.core.metrics import aee, angular_error, endpoint_error_map, valid_mask

from .methods import DIS_MEDIUM, DIS_ULTRAFAST

FRACTIONS = np.arange(20) / 20.0
BORDER_BANDS = ((0, 2), (2, 5), (5, 10), (10, 20), (20, 40), (40, 10**6))  # [lo, hi) px from the nearest edge


def band_aee(err: np.ndarray) -> dict[str, float]:
    """Mean of an error map (H, W) per band of distance to the nearest image edge (BORDER_BANDS); key 'lo-hi'
    px (the last 'lo+'). docs/engine.md, "Mass preservation", reads the mass model's border band with it."""
    h, w = err.shape
    yy, xx = np.mgrid[:h, :w]
    d = np.minimum(np.minimum(yy, h - 1 - yy), np.minimum(xx, w - 1 - xx))
    return {(f"{lo}+" if hi >= 10**6 else f"{lo}-{hi}"): float(err[(d >= lo) & (d < hi)].mean())
            for lo, hi in BORDER_BANDS}


def _curve(err: np.ndarray, order: np.ndarray) -> np.ndarray:
    """Mean of err over the pixels left after removing the first f * n of ``order``, for each f."""
    n = err.size
    tail = np.cumsum(err[order][::-1])[::-1]  # tail[i] = sum of err[order[i:]]
    starts = (FRACTIONS * n).astype(int)
    return tail[starts] / (n - starts)


def ause(flow: np.ndarray, gt: np.ndarray, confidence: np.ndarray) -> float:
    """Area under the sparsification error curve (px) of ``confidence`` (H, W) for flow against gt."""
    m = valid_mask(gt)
    err = endpoint_error_map(flow, gt)[m]
    conf = np.asarray(confidence, np.float64)[m]
    by_conf = np.argsort(conf, kind="stable")  # least confident removed first
    oracle = np.argsort(-err, kind="stable")
    return float(np.mean(_curve(err, by_conf) - _curve(err, oracle)))


def missing_data(gt: np.ndarray, valid: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """The pixels of frame 0 whose data term is garbage: invalid in frame 0, or whose true position in frame
    1 (x + gt, rounded, clipped to the image) is invalid there. (H, W) bool."""
    h, w = gt.shape[:2]
    ys, xs = np.mgrid[0:h, 0:w]
    x1 = np.clip(np.rint(xs + np.nan_to_num(gt[..., 0])), 0, w - 1).astype(int)
    y1 = np.clip(np.rint(ys + np.nan_to_num(gt[..., 1])), 0, h - 1).astype(int)
    return ~valid[0] | ~valid[1][y1, x1]


def score_pair(out: Any, gt: np.ndarray, occluded: np.ndarray | None = None,
               valid: tuple[np.ndarray, np.ndarray] | None = None) -> dict[str, float]:
    """AEE (px), AE (deg), AUSE if ``out`` = (flow, confidence) has a confidence, ``unexplained`` if ``out`` =
    (flow, confidence, unexplained) has the method's unexplained fraction, and with ``occluded``
    ((H, W) bool) ``aee_noc``, the AEE over the known pixels that are not occluded; with the frames'
    validity masks ``valid`` the AEE over the pixels with missing data (:func:`missing_data`),
    ``aee_masked``, and over the rest, ``aee_elsewhere``."""
    flow, conf, unexplained = (*out, None)[:3] if isinstance(out, tuple) else (out, None, None)
    flow = np.asarray(flow, np.float32)
    res = {"aee": aee(flow, gt), "ae": angular_error(flow, gt)}
    if unexplained is not None:
        res["unexplained"] = float(unexplained)
    if occluded is not None:
        res["aee_noc"] = aee(flow, np.where(occluded[..., None], np.inf, gt))
    if valid is not None:
        missing = missing_data(gt, valid)[..., None]
        res["aee_masked"] = aee(flow, np.where(missing, gt, np.inf))
        res["aee_elsewhere"] = aee(flow, np.where(missing, np.inf, gt))
    if conf is not None:
        res["ause"] = ause(flow, gt, conf)
    return res


def _mean(rows: list[dict[str, Any]], key: str) -> float | None:
    vals = [r[key] for r in rows if key in r]
    return float(np.mean(vals)) if vals else None


def summarise(per_pair: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """Means over the pairs (and per variant) of aee, ae, seconds (the per-pair medians), ause, aee_noc
    (the last two over the pairs that have them)."""
    rows = list(per_pair.values())
    out: dict[str, Any] = {k: _mean(rows, k) for k in ("aee", "ae", "seconds", "ause", "aee_noc", "aee_masked",
                                                       "aee_elsewhere")}
    if out["ause"] is not None and out["aee"]:
        out["ause_rel"] = out["ause"] / out["aee"]
    variants = list(dict.fromkeys(r["variant"] for r in rows if r["variant"]))  # in order of appearance
    if variants:
        out["per_variant"] = {v: {k: _mean([r for r in rows if r["variant"] == v], k)
                                  for k in ("aee", "seconds")} for v in variants}
    return out


def add_ratios(methods: dict[str, dict[str, Any]]) -> None:
    """Time (and AEE) ratios of every method against DIS medium and ultrafast of the same run, in place."""
    for ref in (DIS_MEDIUM, DIS_ULTRAFAST):
        if ref not in methods:
            continue
        r = methods[ref]
        for m in methods.values():
            m[f"time_vs_{ref}"] = m["seconds"] / r["seconds"]
            m[f"aee_vs_{ref}"] = m["aee"] / r["aee"]


def similar_time_flags(methods: dict[str, dict[str, Any]], ours: list[str], peers: list[str],
                       factor: float = 1.5) -> dict[str, list[str]]:
    """For each of ``ours``: the peers at most ``factor`` x its time that have a lower mean AEE ("a peer
    of similar time, or faster, beats it"); empty = not beaten."""
    out = {}
    for name in ours:
        me = methods[name]
        out[name] = [p for p in peers if p in methods and methods[p]["seconds"] <= factor * me["seconds"]
                     and methods[p]["aee"] < me["aee"]]
    return out
