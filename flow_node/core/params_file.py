"""Reading a parameter file safely: YAML (a plain mapping, or a ROS params file) with bounded nesting and size,
every failure a FileFormatError naming the file in one line. FlowConfig.from_yaml builds on it (config.py)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from .errors import FileFormatError, short_path

MAX_YAML_DEPTH = 16  # nesting levels a parameter file may have (a ROS params file needs 3)
MAX_YAML_ITEMS = 100_000  # values in all (aliases count each time they are used: no "billion laughs")


def _yaml_reason(exc: Exception) -> str:
    """PyYAML's multi-line error as one line: the problem and where (line, column, 1-based)."""
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    mark = getattr(exc, "problem_mark", None)
    where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    return " ".join(f"{problem}{where}".split())


def _depth(data: Any) -> int:
    """Nesting depth of parsed YAML (a scalar is 0), computed without recursion; more than MAX_YAML_DEPTH
    as soon as it exceeds that or the walk exceeds MAX_YAML_ITEMS values (aliases make cycles and blow-ups)."""
    depth, stack, seen = 0, [(data, 0)], 0
    while stack:
        item, level = stack.pop()
        seen += 1
        if seen > MAX_YAML_ITEMS:
            return MAX_YAML_DEPTH + 1
        if isinstance(item, dict):
            stack += [(v, level + 1) for v in item.values()]
        elif isinstance(item, list):
            stack += [(v, level + 1) for v in item]
        else:
            depth = max(depth, level)
            continue
        depth = max(depth, level + 1)
        if depth > MAX_YAML_DEPTH:
            break
    return depth


def read_mapping(path: str | Path) -> dict[str, Any]:
    """The top-level mapping of the YAML file ``path`` ({} for an empty file); FileFormatError for a missing,
    unreadable or non-regular file, text that is not UTF-8 or not YAML, nesting deeper than MAX_YAML_DEPTH or
    more than MAX_YAML_ITEMS values, and a top level that is not a mapping."""
    import yaml

    shown = short_path(path)
    try:
        regular = not Path(path).exists() or Path(path).is_file()  # a FIFO would block the read
        raw = Path(path).read_bytes() if regular else b""
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise FileFormatError(f"cannot read parameter file {shown}: {reason}") from None
    if not regular:
        raise FileFormatError(f"cannot read parameter file {shown}: not a regular file")
    try:
        data = yaml.safe_load(raw.decode("utf-8"))  # pure Python: the C loader crashes on deep nesting
    except UnicodeDecodeError as exc:
        raise FileFormatError(f"parameter file {shown} is not UTF-8 text (byte 0x{raw[exc.start]:02x} at "
                              f"offset {exc.start})") from None
    except yaml.YAMLError as exc:
        raise FileFormatError(f"{shown} is not valid YAML: {_yaml_reason(exc)}") from None
    except RecursionError:
        raise FileFormatError(f"{shown}: YAML nested too deeply") from None
    if _depth(data) > MAX_YAML_DEPTH:
        raise FileFormatError(f"{shown}: YAML nested deeper than {MAX_YAML_DEPTH} levels or with more "
                              f"than {MAX_YAML_ITEMS} values")
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise FileFormatError(f"{path}: expected a mapping at top level, got {type(data).__name__}")
    return data


def ros_parameters(data: Mapping[str, Any]) -> dict[str, Any] | None:
    """The ``ros__parameters`` mapping of a ROS params file (first node, or ``/**``), else None."""
    for value in data.values():
        if isinstance(value, dict) and isinstance(value.get("ros__parameters"), dict):
            return dict(value["ros__parameters"])
    return None
