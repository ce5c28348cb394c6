"""What ``flow_bag eval`` produces, as data: the options of a run, the record of every frame, the runs of one
bag (:class:`EvalResult`), and for a batch the job and outcome of each bag.

A leaf of the bag tools: the evaluation fills these, the reports read them, the batch ships them to its
workers, and none of those modules needs another one for its types.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core.config import FlowConfig
from ..pipeline.motion import MotionDetector
from ..pipeline.stream import FlowStream

NODE_NAMESPACE = "/flow_node"  # the node's default name: its ~/flow is /flow_node/flow
BATCH_FORMAT = 1  # part of every batch cache key: bump when the per-bag output changes meaning


@dataclass(frozen=True)
class EvalOptions:
    """Topics (None: detect), colour scale in px (None: the node's default), PNG frame choice ('auto',
    'all', 'none' or comma-separated frame indices), whether to show a progress bar, and whether to write
    the derived motion outputs (``--motion``: flow_node.pipeline.derived) too."""

    image_topic: str | None = None
    gt_topic: str | None = None
    max_flow: float | None = None
    png_frames: str = "auto"
    progress: bool = True
    motion: bool = False


@dataclass
class FrameRecord:
    """One processed image: its bag index and stamps; for a pair, time, iterations, magnitude statistics
    and (with ground truth) AEE px, AE degrees and the confidence's ROC AUC against the real error (None
    when every pixel is right or every one wrong). ``skipped`` holds the reason an image was unusable.
    ``motion`` (``--motion``): flow_node.bag.motion_topics.motion_record, with ground truth plus
    ``vs_ground_truth`` (motion_topics.truth_errors)."""

    index: int
    stamp_ns: int
    previous_stamp_ns: int | None = None
    seconds: float | None = None
    iterations: int | None = None
    magnitude: dict[str, float] | None = None
    aee: float | None = None
    ae: float | None = None
    confidence_auc: float | None = None
    skipped: str | None = None
    note: str | None = None
    motion: dict[str, Any] | None = None


@dataclass
class ModelRun:
    """The records of one configuration over the whole bag (and its ``motion detected`` flag's state)."""

    label: str
    config: FlowConfig
    stream: FlowStream
    records: list[FrameRecord] = field(default_factory=list)
    detector: MotionDetector = field(default_factory=MotionDetector)

    def topic(self, name: str, primary: bool) -> str:
        """Output topic: the node's names for the first model, ``/flow_node/<model>/...`` for the others."""
        return f"{NODE_NAMESPACE}/{name}" if primary else f"{NODE_NAMESPACE}/{self.label}/{name}"


@dataclass
class Drawn:
    """What the PNGs of one chosen frame need: the frame, the flows per model and the ground truth."""

    index: int
    stamp_ns: int
    frame: np.ndarray
    flows: dict[str, np.ndarray] = field(default_factory=dict)
    gt: np.ndarray | None = None


@dataclass
class EvalResult:
    """Everything the report is made of."""

    bag: str
    image_topic: str
    gt_topic: str | None
    images: int
    runs: list[ModelRun]
    drawn: list[Drawn]
    color_max_flow: float
    wall_seconds: float = 0.0
    warnings: list[str] = field(default_factory=list)  # one line each, for stderr
    recovered: dict[str, Any] | None = None  # what a bag without its MCAP summary still gave (bagio)
    motion: bool = False  # the derived motion outputs are written and reported (--motion)


@dataclass(frozen=True)
class BagJob:
    """One bag to evaluate: its path, its output folder, the configs and options, and the digest of
    everything but the bag that the cache key covers."""

    bag: str
    name: str
    output: str
    configs: tuple[FlowConfig, ...]
    opts: EvalOptions
    config_digest: str


@dataclass
class BagOutcome:
    """What became of one bag: ``status`` is 'done', 'skipped' (cached) or 'failed' (with ``reason``);
    ``report`` is the bag's report.json as data (None when failed); ``seconds`` the task's wall time;
    ``host`` and ``pid`` the machine and process that ran it."""

    bag: str
    name: str
    status: str
    reason: str | None = None
    key: str | None = None
    seconds: float = 0.0
    host: str = ""
    pid: int = 0
    report: dict[str, Any] | None = field(default=None, repr=False)
