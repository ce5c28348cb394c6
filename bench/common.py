"""Shared benchmark helpers: the Middlebury training pairs, timing one method, and the results files.

Frames are grey float32 in [0, 1] (BT.601 luma of the RGB PNG). Flow is float32 (H, W, 2), channel 0 = u (x),
1 = v (y), I1(x + flow) ~ I0(x). The peers live with the suite (bench/suite/methods.py).
"""

from __future__ import annotations

import json
import platform
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from flow_node.core.api import FlowEstimator, to_grey
from flow_node.core.config import FlowConfig
from flow_node.core.flowio import read_flo, read_image
from flow_node.core.metrics import aee, angular_error

REPO = Path(__file__).resolve().parent.parent
DEFAULT_DATA = REPO.parent / "shared" / "data" / "middlebury"
SEQUENCES = ("Dimetrodon", "Grove2", "Grove3", "Hydrangea", "RubberWhale", "Urban2", "Urban3", "Venus")

# A method maps two grey float32 (H, W) frames in [0, 1] to flow (H, W, 2) float32.
Method = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Pair:
    """One evaluation pair: grey frames (H, W) float32 in [0, 1] and ground truth (H, W, 2) (unknown >= 1e9)."""

    name: str
    i0: np.ndarray
    i1: np.ndarray
    gt: np.ndarray


def load_middlebury(data: Path, names: tuple[str, ...] = SEQUENCES) -> list[Pair]:
    """frame10 -> frame11 with flow10.flo for each named sequence under ``data``."""
    if not data.is_dir():
        raise SystemExit(f"Middlebury data not found at {data}; pass --data DIR")
    pairs = []
    for name in names:
        seq = data / name
        i0 = to_grey(read_image(seq / "frame10.png"), "frame10")
        i1 = to_grey(read_image(seq / "frame11.png"), "frame11")
        pairs.append(Pair(name, i0, i1, read_flo(seq / "flow10.flo")))
    return pairs


def flow_node_method(cfg: FlowConfig) -> Method:
    """The engine with ``cfg`` (JIT warm-up done here, outside any timing)."""
    est = FlowEstimator(cfg)
    est.warmup()
    return lambda i0, i1: est.estimate(i0, i1).flow


def backend_of(cfg: FlowConfig) -> str:
    """The backend ``cfg`` resolves to on this machine (numba or numpy)."""
    return FlowEstimator(cfg).backend


# ------------------------------------------------------------------------------------------------ scoring
def evaluate(method: Method, pairs: list[Pair]) -> dict[str, Any]:
    """Run ``method`` on every pair: per-sequence AEE (px), AE (deg), seconds; plus their means."""
    per: dict[str, dict[str, float]] = {}
    for p in pairs:
        start = time.perf_counter()
        flow = method(p.i0, p.i1)
        secs = time.perf_counter() - start
        per[p.name] = {"aee": aee(flow, p.gt), "ae": angular_error(flow, p.gt), "seconds": secs}
    return {"per_sequence": per, **summarise(per)}


def summarise(per: dict[str, dict[str, float]]) -> dict[str, float]:
    """Means over sequences of every metric in ``per``."""
    keys = next(iter(per.values())).keys()
    return {f"mean_{k}": float(np.mean([v[k] for v in per.values()])) for k in keys}


def machine() -> dict[str, Any]:
    """Where a result was measured (for the JSON files)."""
    import os

    return {"python": platform.python_version(), "machine": platform.machine(), "cpus": os.cpu_count()}


def write_json(path: Path, payload: dict[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(payload, indent=1, sort_keys=False) + "\n")
