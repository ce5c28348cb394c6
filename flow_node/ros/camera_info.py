"""CameraInfo for the node's output grid: the input camera's calibration scaled to the processing resolution.

With ``input_scale`` s < 1 the flow is published on a grid s times the input's size, so the camera matrix
that goes with it is the input's scaled. Scaling keeps pixel centres aligned the way OpenCV's resize does
(output pixel centre u' = (u + 0.5) * sx - 0.5): fx' = sx * fx, cx' = (cx + 0.5) * sx - 0.5, and the same
for the projection matrix P (its Tx, Ty scale with fx, fy); D and R are unchanged. The topic the node
listens on follows image_transport's CameraSubscriber: ``camera_info`` beside the (remapped) image topic.
"""

from __future__ import annotations

from sensor_msgs.msg import CameraInfo
from std_msgs.msg import Header

from .names import camera_info_topic

__all__ = ["camera_info_topic", "scaled_camera_info", "unscalable"]


def unscalable(info: CameraInfo) -> str | None:
    """Why ``info`` cannot be scaled here (binning or a region of interest set, or no size), else None."""
    if info.width == 0 or info.height == 0:
        return "camera_info has no width/height"
    if info.binning_x > 1 or info.binning_y > 1:
        return "camera_info with binning is not rescaled"
    roi = info.roi
    if roi.width or roi.height or roi.x_offset or roi.y_offset:
        return "camera_info with a region of interest is not rescaled"
    return None


def _centre(c: float, s: float) -> float:
    """A principal point coordinate after scaling by ``s`` with pixel centres aligned."""
    return (c + 0.5) * s - 0.5


def scaled_camera_info(info: CameraInfo, width: int, height: int, header: Header) -> CameraInfo:
    """``info`` (no binning, no ROI: see :func:`unscalable`) for an image of ``width`` x ``height`` covering the
    same field of view, with ``header``. A size equal to the input's returns its calibration unchanged."""
    sx, sy = width / info.width, height / info.height
    k = [float(v) for v in info.k]
    k[0], k[1], k[2] = k[0] * sx, k[1] * sx, _centre(k[2], sx)
    k[4], k[5] = k[4] * sy, _centre(k[5], sy)
    p = [float(v) for v in info.p]
    p[0], p[1], p[2], p[3] = p[0] * sx, p[1] * sx, _centre(p[2], sx), p[3] * sx
    p[5], p[6], p[7] = p[5] * sy, _centre(p[6], sy), p[7] * sy
    return CameraInfo(header=header, height=height, width=width, distortion_model=info.distortion_model,
                      d=list(info.d), k=k, r=list(info.r), p=p)
