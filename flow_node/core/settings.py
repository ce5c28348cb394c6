"""Settings dataclasses that describe themselves: each field carries its description and its valid range or
choices (:func:`setting`), so validation, the ROS parameter descriptors, the YAML files and the CLI help are
derived from one table. Used by :class:`~flow_node.core.config.FlowConfig` and the derived outputs' settings
(:class:`~flow_node.pipeline.derived.MotionSettings`, nested: a field whose default is such a dataclass
contributes its own fields under ``<field>.``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from .errors import ConfigError

TYPES: dict[str, type] = {"int": int, "float": float, "str": str, "bool": bool}


def setting(default: Any, help: str, *, lo: float | None = None, hi: float | None = None,
            choices: tuple[Any, ...] | None = None, lo_open: bool = False) -> Any:
    """A dataclass field carrying its description and its valid range or choices."""
    meta = {"help": help, "lo": lo, "hi": hi, "choices": choices, "lo_open": lo_open}
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class FieldInfo:
    """What an entry point needs to expose a settings field (ROS descriptor, CLI help)."""

    name: str
    type: type
    default: Any
    help: str
    lo: float | None
    hi: float | None
    choices: tuple[Any, ...] | None


def check_field(f: dataclasses.Field, value: Any) -> Any:
    """Type-check, coerce (int -> float) and range-check one field value; returns the value to store."""
    name, m = f.name, f.metadata
    kind = str(f.type)
    if kind == "str":
        if not isinstance(value, str):
            raise ConfigError(f"{name}: expected a string, got {type(value).__name__} {value!r}")
    elif kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            if isinstance(value, float) and value.is_integer():
                value = int(value)
            else:
                raise ConfigError(f"{name}: expected an integer, got {type(value).__name__} {value!r}")
    elif kind == "float":
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{name}: expected a number, got {type(value).__name__} {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise ConfigError(f"{name}: must be finite, got {value}")
    if m["choices"] is not None and value not in m["choices"]:
        raise ConfigError(f"{name}: {value!r} is not one of {', '.join(map(str, m['choices']))}")
    lo, hi = m["lo"], m["hi"]
    if lo is not None and (value < lo or (m["lo_open"] and value == lo)):
        op = ">" if m["lo_open"] else ">="
        raise ConfigError(f"{name}: must be {op} {lo}, got {value}")
    if hi is not None and value > hi:
        raise ConfigError(f"{name}: must be <= {hi}, got {value}")
    return value


def check_fields(obj: Any) -> None:
    """Check (and coerce in place) every :func:`setting` field of the dataclass instance ``obj``, frozen or
    not; ConfigError with the field's name and the reason for the first invalid one."""
    for f in dataclasses.fields(obj):
        if "help" in f.metadata:
            object.__setattr__(obj, f.name, check_field(f, getattr(obj, f.name)))


def fields_info(cls: type, prefix: str = "") -> list[FieldInfo]:
    """Name, type, default, description and range of every :func:`setting` field of the dataclass ``cls``
    (defaults as ``cls()`` resolves them), nested dataclasses flattened to ``<prefix><field>.<name>``."""
    defaults = cls()
    out = []
    for f in dataclasses.fields(cls):
        value = getattr(defaults, f.name)
        if dataclasses.is_dataclass(value):
            out += fields_info(type(value), f"{prefix}{f.name}.")
        elif "help" in f.metadata:
            m = f.metadata
            out.append(FieldInfo(prefix + f.name, TYPES[str(f.type)], value, m["help"], m["lo"], m["hi"],
                                 m["choices"]))
    return out


def from_flat(cls: type, values: Mapping[str, Any], prefix: str = "") -> Any:
    """An instance of the dataclass ``cls`` from flat ``values`` named as :func:`fields_info` names them
    (missing names take the defaults, other names are ignored); ConfigError naming the flat field."""
    defaults = cls()
    kwargs: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        value = getattr(defaults, f.name)
        if dataclasses.is_dataclass(value):
            kwargs[f.name] = from_flat(type(value), values, f"{prefix}{f.name}.")
        elif prefix + f.name in values:
            kwargs[f.name] = values[prefix + f.name]
    try:
        return cls(**kwargs)
    except ConfigError as exc:
        raise ConfigError(f"{prefix}{exc}") from None
