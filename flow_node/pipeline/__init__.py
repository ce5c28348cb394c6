"""The per-frame pipeline shared by the ROS node and the bag tools: codec (message <-> array), stream
(previous frame, reset rules, engine call, outputs) and the derived motion outputs (dominant motion, time
to contact, moving objects). Imports neither rclpy nor rosbags."""

from .codec import (
    MalformedImage,
    UnsupportedEncoding,
    array_to_image_fields,
    compressed_to_array,
    decode,
    image_to_array,
)
from .derived import MOTION_TOPICS, MotionAnalysis, MotionSettings
from .expansion import FocusOfExpansion, RegionTTC, TimeToContact, divergence, focus_of_expansion, region_ttc
from .motion import (
    DominantMotion,
    Hysteresis,
    MaskThreshold,
    MotionDetector,
    dominant_motion,
    moving_fraction,
    moving_mask,
)
from .stream import FlowOutput, FlowStream, FlowSummary, StreamSettings, magnitude, summarise

__all__ = ["MalformedImage", "UnsupportedEncoding", "array_to_image_fields", "compressed_to_array", "decode",
           "image_to_array", "FlowOutput", "FlowStream", "FlowSummary", "StreamSettings", "magnitude",
           "summarise", "MOTION_TOPICS", "MotionAnalysis", "MotionSettings", "FocusOfExpansion", "RegionTTC",
           "TimeToContact", "divergence", "focus_of_expansion", "region_ttc", "DominantMotion", "Hysteresis",
           "MaskThreshold", "MotionDetector", "dominant_motion", "moving_fraction", "moving_mask"]
