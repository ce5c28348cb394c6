"""Flow units on the wire: pixels per frame (the engine's) or pixels per second (a velocity).

With latest-wins dropping, a published pair can span several camera frames, so px/frame alone cannot be
turned into a velocity; px/s divides by the pair's own interval (newer stamp - earlier stamp). Plain numpy.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..core.errors import InputError
from .stream import FlowOutput

FLOW_UNITS = ("px/frame", "px/s")


def units_factor(units: str, interval_ns: int) -> float:
    """What px/frame flow is multiplied by to be in ``units``, for a pair ``interval_ns`` apart.

    1 for px/frame; 1 / interval in seconds for px/s, where an interval <= 0 (equal stamps) raises
    InputError: no velocity can be given for it.
    """
    if units == "px/frame":
        return 1.0
    if units != "px/s":
        raise InputError(f"flow_units: {units!r} is not one of {', '.join(FLOW_UNITS)}")
    if interval_ns <= 0:
        raise InputError(f"flow_units px/s: the pair's stamps are {interval_ns} ns apart, no velocity")
    return 1e9 / interval_ns


def output_in_units(out: FlowOutput, units: str) -> FlowOutput:
    """``out`` with its flow in ``units`` over its own pair's interval (magnitude and colour follow, computed
    on first use); ``out`` itself when that is px/frame. InputError as :func:`units_factor`."""
    factor = units_factor(units, out.stamp_ns - out.previous_stamp_ns)
    if factor == 1.0:
        return out
    return replace(out, flow=(out.flow * np.float32(factor)).astype(np.float32, copy=False),
                   frame_flow=out.flow if out.frame_flow is None else out.frame_flow, _magnitude=None, _color=None,
                   _summary=None)
