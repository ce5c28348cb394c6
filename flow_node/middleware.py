"""The Fast DDS profile a process of the package publishes with, and the line that says which one is in effect.

Environment only (no rclpy, no project imports), so that the node (``ros/``) and ``flow_bag play`` (``bag/``)
share it without one importing the other. Like process.py's settings, it is applied only by an executable's
``main()``, before ``rclpy.init`` (docs/node.md, "Middleware").
"""

from __future__ import annotations

import os
from collections.abc import Mapping, MutableMapping
from pathlib import Path

PROFILE_VAR = "FASTRTPS_DEFAULT_PROFILES_FILE"  # Fast DDS 2.x (Jazzy): XML profiles loaded at participant creation
TRANSPORTS_VAR = "FASTDDS_BUILTIN_TRANSPORTS"  # the user's choice of Fast DDS's built-in transports
PROFILE_NAME = "fastdds_localhost.xml"
FAST_DDS_RMWS = ("rmw_fastrtps_cpp", "rmw_fastrtps_dynamic_cpp")


def rmw_name(environ: Mapping[str, str] = os.environ) -> str:
    """The RMW this process will load: ``RMW_IMPLEMENTATION``, else Jazzy's default (Fast DDS)."""
    return environ.get("RMW_IMPLEMENTATION", FAST_DDS_RMWS[0])


def shipped_dds_profile() -> Path | None:
    """The package's Fast DDS profile: installed (share/flow_node/config, found through the ament index) or,
    run from a checkout, config/ beside the package; None if neither exists."""
    candidates = [Path(__file__).resolve().parents[1] / "config" / PROFILE_NAME]
    try:
        from ament_index_python.packages import get_package_share_directory

        candidates.insert(0, Path(get_package_share_directory("flow_node")) / "config" / PROFILE_NAME)
    except (ImportError, LookupError, OSError):  # no ament index / not installed through colcon / no prefix path
        pass
    return next((p for p in candidates if p.is_file()), None)


def use_shipped_dds_profile(environ: MutableMapping[str, str] = os.environ) -> str | None:
    """Point Fast DDS at the package's profile (32 MB shared-memory segments, UDP kept: docs/node.md,
    "Middleware") for this process, unless the user chose: their own profile file (``FASTRTPS_DEFAULT_PROFILES_FILE``,
    even empty), ``FASTDDS_BUILTIN_TRANSPORTS``, or another RMW. The one rule for ros2 run, ros2 launch and
    python -m. Must run before ``rclpy.init``. Returns the path it set, or None if it left the environment alone."""
    if PROFILE_VAR in environ or TRANSPORTS_VAR in environ or rmw_name(environ) not in FAST_DDS_RMWS:
        return None
    path = shipped_dds_profile()
    if path is None:
        return None
    environ[PROFILE_VAR] = str(path)
    return str(path)


def middleware_line(environ: Mapping[str, str] = os.environ) -> str:
    """What the process runs on, for the start-up log: the RMW and, for Fast DDS, the profile file in effect
    (after :func:`use_shipped_dds_profile`) or the transports the user chose."""
    rmw = rmw_name(environ)
    if rmw not in FAST_DDS_RMWS:
        return f"middleware {rmw}"
    if environ.get(PROFILE_VAR):
        return f"middleware {rmw}, profile {environ[PROFILE_VAR]}"
    if TRANSPORTS_VAR in environ:
        return f"middleware {rmw}, built-in transports {environ[TRANSPORTS_VAR]}"
    return f"middleware {rmw}, Fast DDS defaults"
