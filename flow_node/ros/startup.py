"""Start-up of the node's process: checks of its command line (a one-line reason instead of rcl's traceback)
and the middleware profile it runs with.

rcl parses ``--params-file`` inside ``rclpy.init`` and fails with an RCLError whose text carries C source
locations ("Couldn't parse params file: '--params-file x.yaml'. Error: Error opening YAML file, at
/project/src/parser.c:271, ..."); a relative path is resolved against the current directory, not the
package. :func:`check_params_files` says which file and why before rcl gets there.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping, MutableMapping, Sequence
from pathlib import Path

import yaml

from ..core.config import FlowConfig
from ..core.errors import ConfigError, FileFormatError, one_line


def params_files(args: Sequence[str]) -> list[str]:
    """The ``--params-file FILE`` arguments of a ROS command line (inside ``--ros-args`` sections)."""
    out, in_ros = [], False
    it = iter(args)
    for arg in it:
        if arg == "--ros-args":
            in_ros = True
        elif arg == "--":
            in_ros = False
        elif in_ros and arg == "--params-file":
            out.append(next(it, ""))
    return out


def _has_parameters(node: object) -> bool:
    """True if ``node`` is a mapping with a ``ros__parameters`` mapping in it, directly or under a namespace
    (rcl accepts ``/ns: {node: {ros__parameters: ...}}``)."""
    if not isinstance(node, dict):
        return False
    if isinstance(node.get("ros__parameters"), dict):
        return True
    return any(_has_parameters(v) for v in node.values())


def check_params_file(path: str) -> None:
    """ConfigError with a one-line reason if ``path`` cannot be read, is not YAML (FlowConfig.from_yaml's
    checks: encoding, syntax, nesting) or is not a ROS parameter file. Invalid values are left to the node,
    which validates them together with every other source (several files, ``-p``)."""
    if not path:
        raise ConfigError("--params-file needs a file name")
    try:
        FlowConfig.from_yaml(path)
    except FileFormatError as exc:
        hint = ""
        if not Path(path).is_absolute() and not Path(path).exists():
            hint = (f" (relative to the current directory {os.getcwd()}; installed files are in "
                    "$(ros2 pkg prefix flow_node)/share/flow_node/config/)")
        raise ConfigError(f"{exc}{hint}") from None
    except ConfigError:
        pass
    data = yaml.safe_load(Path(path).read_text(encoding="utf-8"))  # read fine just above
    if not isinstance(data, dict) or not data or not all(_has_parameters(v) for v in data.values()):
        raise ConfigError(f"params file {path} is not a ROS parameter file: expected "
                          "'<node name or /**>: {ros__parameters: {name: value, ...}}'")


def check_params_files(args: Sequence[str]) -> None:
    """:func:`check_params_file` for every ``--params-file`` of ``args``."""
    for path in params_files(args):
        check_params_file(path)


def rcl_error_line(exc: Exception) -> str:
    """rcl's error text without its C source locations (", at /path/file.c:123"), on one line."""
    text = re.sub(r",? at [^\s,]+\.c(pp)?:\d+", "", str(exc))
    return one_line(text, None)


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
    candidates = [Path(__file__).resolve().parents[2] / "config" / PROFILE_NAME]
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
