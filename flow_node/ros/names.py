"""Topic names derived from others (plain Python, no rclpy): shared by the node and its security policy."""

from __future__ import annotations


def camera_info_topic(image_topic: str) -> str:
    """The CameraInfo topic beside an image topic, as image_transport's CameraSubscriber finds it:
    ``/camera/image_raw`` -> ``/camera/camera_info``, ``image`` (relative) -> ``camera_info``."""
    base, sep, _ = image_topic.rpartition("/")
    return f"{base}{sep}camera_info"
