"""Start-up checks of the node's command line: a one-line reason instead of rcl's traceback.

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

from ..core.errors import ConfigError


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


def _yaml_problem(exc: yaml.YAMLError) -> str:
    """A YAML error as one line: the problem and its line/column (1-based)."""
    mark = getattr(exc, "problem_mark", None)
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    return f"{problem}{where}"


def _has_parameters(node: object) -> bool:
    """True if ``node`` is a mapping with a ``ros__parameters`` mapping in it, directly or under a namespace
    (rcl accepts ``/ns: {node: {ros__parameters: ...}}``)."""
    if not isinstance(node, dict):
        return False
    if isinstance(node.get("ros__parameters"), dict):
        return True
    return any(_has_parameters(v) for v in node.values())


def check_params_file(path: str) -> None:
    """ConfigError with a one-line reason if ``path`` cannot be read or is not a ROS parameter file."""
    if not path:
        raise ConfigError("--params-file needs a file name")
    p = Path(path)
    hint = ""
    if not p.is_absolute():
        hint = (f" (relative to the current directory {os.getcwd()}; installed files are in "
                "$(ros2 pkg prefix flow_node)/share/flow_node/config/)")
    try:
        text = p.read_text()
    except OSError as exc:
        raise ConfigError(f"cannot read params file {path}: {exc.strerror}{hint}") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"params file {path} is not valid YAML: {_yaml_problem(exc)}") from None
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
    return " ".join(text.split())
