"""The per-frame pipeline shared by the ROS node and the bag tools: codec (message <-> array) and stream
(previous frame, reset rules, engine call, outputs). Imports neither rclpy nor rosbags."""

from .codec import (
    MalformedImage,
    UnsupportedEncoding,
    array_to_image_fields,
    compressed_to_array,
    decode,
    image_to_array,
)
from .stream import FlowOutput, FlowStream, FlowSummary, StreamSettings, magnitude, summarise

__all__ = ["MalformedImage", "UnsupportedEncoding", "array_to_image_fields", "compressed_to_array", "decode",
           "image_to_array", "FlowOutput", "FlowStream", "FlowSummary", "StreamSettings", "magnitude",
           "summarise"]
