"""Flow units on the wire: pixels per frame (the engine's) or pixels per second (a velocity).

The setting belongs to the stream (``StreamSettings.flow_units``, validated there; :class:`FlowStream` applies
it, :meth:`FlowOutput.in_units`). This module keeps the names the ROS node imports
(``output_in_units``, ``FLOW_UNITS``) until the node hands ``flow_units`` to its stream instead of converting
each output itself.
"""

from __future__ import annotations

from .stream import FLOW_UNITS, FlowOutput, units_factor

__all__ = ["FLOW_UNITS", "output_in_units", "units_factor"]


def output_in_units(out: FlowOutput, units: str) -> FlowOutput:
    """``out.in_units(units)``: ``out`` with its flow in ``units`` over its own pair's interval."""
    return out.in_units(units)
