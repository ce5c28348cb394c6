"""The engine: models, operators, primal-dual solver, coarse-to-fine driver. No ROS imports here."""

from .api import FlowEstimator, FlowResult, estimate_flow, to_grey
from .config import MODELS, PRESETS, FlowConfig, fields_info
from .errors import ConfigError, FileFormatError, FlowError, InputError
from .flowio import flow_to_color, read_flo, read_image, write_flo
from .metrics import aee, angular_error, endpoint_error_map
from .volume import estimate_volume

__all__ = [
    "MODELS", "PRESETS", "ConfigError", "FileFormatError", "FlowConfig", "FlowError", "FlowEstimator",
    "FlowResult", "InputError", "aee", "angular_error", "endpoint_error_map", "estimate_flow",
    "estimate_volume", "fields_info", "flow_to_color", "read_flo", "read_image", "to_grey", "write_flo",
]
