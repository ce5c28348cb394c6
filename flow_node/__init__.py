"""flow_node: variational dense optical flow for ROS 2. ``from flow_node import estimate_flow, FlowConfig``."""

from .core import (
    ConfigError,
    FileFormatError,
    FlowConfig,
    FlowError,
    FlowEstimator,
    InputError,
    aee,
    angular_error,
    estimate_flow,
    flow_to_color,
    read_flo,
    write_flo,
)

__all__ = [
    "ConfigError", "FileFormatError", "FlowConfig", "FlowError", "FlowEstimator", "InputError", "aee",
    "angular_error", "estimate_flow", "flow_to_color", "read_flo", "write_flo",
]
__version__ = "0.1.0"
