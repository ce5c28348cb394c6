"""Start-up of the node's process: checks of its command line (a one-line reason instead of rcl's traceback).
The middleware profile it runs with is flow_node/middleware.py's (``flow_bag play`` applies it too).

rcl parses ``--params-file`` inside ``rclpy.init`` and fails with an RCLError whose text carries C source
locations ("Couldn't parse params file: '--params-file x.yaml'. Error: Error opening YAML file, at
/project/src/parser.c:271, ..."); a relative path is resolved against the current directory, not the
package. :func:`check_params_files` says which file and why before rcl gets there.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
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
