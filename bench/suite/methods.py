"""The methods the suite compares: flow_node configs (presets and the plain FlowConfig()) and the peers.

A method has two steps: ``prepare(sample)`` (untimed) and ``run(prepared)`` (timed), which returns the flow
(H, W, 2) float32, or (flow, confidence) with a per-pixel confidence (H, W) in [0, 1], or (flow, confidence,
unexplained) with flow_node's FlowResult.unexplained. What each method is given: docs/suite.md, "Decisions".
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, Protocol

import numpy as np

from flow_node.core.api import FlowEstimator, to_grey
from flow_node.core.config import FlowConfig
from flow_node.core.initialise import to_u8
from flow_node.core.presets import GENERAL_PRESETS

from .data import Sample

Output = Any  # np.ndarray flow, or (flow, confidence | None), or (flow, confidence | None, unexplained)

PRESET_NAMES = GENERAL_PRESETS  # quality, balanced, realtime, fastest (joint and stream_*: --method)
DEFAULT_NAME = "default"  # the plain FlowConfig()
DIS_MEDIUM, DIS_ULTRAFAST = "dis_medium", "dis_ultrafast"
PEER_NAMES = (DIS_ULTRAFAST, DIS_MEDIUM, "skimage_tvl1", "dualtvl1")
MASKED_SUFFIX = "+mask"  # a flow_node method so named is given the samples' validity masks (FlowNode.use_mask)
SLOW_PEERS = ("skimage_tvl1", "dualtvl1")


class Method(Protocol):
    def prepare(self, sample: Sample) -> Any: ...

    def run(self, prepared: Any) -> Output: ...


def unit_grey(frame: np.ndarray, bits: int) -> np.ndarray:
    """Grey float32 (H, W) in [0, 1] with the content's full scale (2**bits - 1) at 1."""
    g = to_grey(frame)
    if frame.dtype == np.uint16 and bits < 16:
        g = np.minimum(g * np.float32(65535.0 / (2**bits - 1)), np.float32(1.0))
    return g


class FlowNode:
    """flow_node with one config; JIT warm-up at construction. Returns (flow, confidence or None, unexplained):
    a FlowResult with a ``confidence`` attribute (H, W) is reported as such, and its unexplained fraction.
    ``use_mask``: given the sample's validity masks (``Sample.valid``, the regime ``missing``), else not told which
    pixels are garbage."""

    def __init__(self, config: FlowConfig, use_mask: bool = False) -> None:
        self.config = config
        self.use_mask = use_mask
        self.estimator = FlowEstimator(config)
        self.estimator.warmup()

    def prepare(self, sample: Sample) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray] | None]:
        return sample.f0, sample.f1, (sample.valid if self.use_mask else None)

    def run(self, prepared: tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray] | None]) -> Output:
        res = self.estimator.estimate(prepared[0], prepared[1], mask=prepared[2])
        return res.flow, getattr(res, "confidence", None), res.unexplained


class OpenCVPeer:
    """An OpenCV optical-flow object with ``calc(u8, u8, None)``: DIS presets, contrib DualTVL1."""

    def __init__(self, algo: Any) -> None:
        self.algo = algo

    def prepare(self, sample: Sample) -> tuple[np.ndarray, np.ndarray]:
        return to_u8(unit_grey(sample.f0, sample.bits)), to_u8(unit_grey(sample.f1, sample.bits))

    def run(self, prepared: tuple[np.ndarray, np.ndarray]) -> Output:
        return self.algo.calc(prepared[0], prepared[1], None)


class SkimageTVL1:
    """scikit-image optical_flow_tvl1 with its defaults; (row, col) flow reordered to (u, v)."""

    def __init__(self) -> None:
        from skimage.registration import optical_flow_tvl1

        self.fn = optical_flow_tvl1

    def prepare(self, sample: Sample) -> tuple[np.ndarray, np.ndarray]:
        return unit_grey(sample.f0, sample.bits), unit_grey(sample.f1, sample.bits)

    def run(self, prepared: tuple[np.ndarray, np.ndarray]) -> Output:
        rc = self.fn(*prepared)
        return np.stack([rc[1], rc[0]], axis=-1)


def _dis(preset: str) -> OpenCVPeer:
    import cv2

    return OpenCVPeer(cv2.DISOpticalFlow_create(getattr(cv2, f"DISOPTICAL_FLOW_PRESET_{preset}")))


def _dualtvl1() -> OpenCVPeer:
    import cv2

    return OpenCVPeer(cv2.optflow.DualTVL1OpticalFlow_create())


PEERS: dict[str, Callable[[], Method]] = {
    DIS_ULTRAFAST: lambda: _dis("ULTRAFAST"),
    DIS_MEDIUM: lambda: _dis("MEDIUM"),
    "skimage_tvl1": SkimageTVL1,
    "dualtvl1": _dualtvl1,
}


def default_configs() -> dict[str, FlowConfig]:
    """Every preset and the plain FlowConfig() ('default')."""
    out = {name: FlowConfig.preset(name) for name in PRESET_NAMES}
    out[DEFAULT_NAME] = FlowConfig()
    return out


def parse_method(spec: str) -> tuple[str, FlowConfig]:
    """A ``--method NAME=BASE[,key=value...]`` argument -> (name, config); BASE is a preset or ``default``
    (the plain FlowConfig()). The suite, its stream regime and the stage costs read --method with it."""
    name, sep, rest = spec.partition("=")
    base, *sets = rest.split(",")
    if not sep or not name or not base:
        raise SystemExit(f"--method: expected NAME=BASE[,key=value...], got {spec!r}")
    return name, (FlowConfig() if base == "default" else FlowConfig.preset(base)).with_overrides(sets)


def build(methods: Mapping[str, FlowConfig | Method] | None, peers: tuple[str, ...]) -> dict[str, Method]:
    """Instantiate the compared methods: ``methods`` (FlowConfigs are wrapped in :class:`FlowNode`, given the
    samples' validity masks when the name ends in MASKED_SUFFIX; None = :func:`default_configs`) followed by
    the named peers."""
    chosen: dict[str, FlowConfig | Method] = dict(default_configs() if methods is None else methods)
    unknown = [p for p in peers if p not in PEERS]
    if unknown:
        raise ValueError(f"unknown peer(s) {', '.join(unknown)}; choose from {', '.join(PEERS)}")
    out: dict[str, Method] = {name: FlowNode(m, name.endswith(MASKED_SUFFIX)) if isinstance(m, FlowConfig) else m
                              for name, m in chosen.items()}
    for p in peers:
        out.setdefault(p, PEERS[p]())
    return out


def describe(method: Method) -> dict[str, Any]:
    """What the JSON records about a method: the config of a flow_node method, else its class."""
    if isinstance(method, FlowNode):
        return {"kind": "flow_node", "backend": method.estimator.backend, "config": method.config.to_dict(),
                "use_mask": method.use_mask}
    return {"kind": type(method).__name__}
