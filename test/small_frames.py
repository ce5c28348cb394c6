"""Solver settings for the tests' small frames (80x60 to 128x96), in the three forms the entry points take.

The realtime preset's solver, solved at full resolution (the preset's ``finest_level`` 1 is meant for
camera-sized frames), on the numpy backend (no JIT compile, deterministic).
"""

from __future__ import annotations

from typing import Any

from flow_node.core.config import FlowConfig

PARAMS: dict[str, Any] = {"preset": "realtime", "finest_level": 0, "backend": "numpy"}  # ROS parameters
CONFIG = FlowConfig.from_mapping(PARAMS)
CLI_ARGS = ["--preset", "realtime"] + [a for k, v in PARAMS.items() if k != "preset" for a in ("--set", f"{k}={v}")]
