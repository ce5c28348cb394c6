"""The exceptions of flow_node: one base class, a few specific kinds.

Every error a user can cause (bad parameters, bad images, unreadable files) is raised as one of these with
a message that names the problem; callers catch :class:`FlowError` to handle all of them.
"""

from __future__ import annotations

import os

MESSAGE_LIMIT = 400  # characters of one error line


def one_line(text: object, limit: int | None = MESSAGE_LIMIT) -> str:
    """``text`` on one line (whitespace runs collapsed), cut to at most ``limit`` characters (None: no cut)."""
    flat = " ".join(str(text).split())
    return flat if limit is None or len(flat) <= limit else flat[: limit - 3] + "..."


class FlowError(Exception):
    """Base class of every error flow_node raises on purpose."""


class ConfigError(FlowError, ValueError):
    """An invalid configuration: unknown key, wrong type, value out of range, bad combination."""


class InputError(FlowError, ValueError):
    """Input data the engine cannot use: wrong shape, dtype, size mismatch, NaN/inf, too small."""


class FileFormatError(FlowError, OSError):
    """A file that cannot be read or written in the expected format (.flo, PNG, YAML, bag)."""


class ClusterError(FlowError, OSError):
    """A compute cluster (Dask scheduler) that cannot be started or reached."""


class NonFiniteResult(InputError):
    """The engine produced NaN or infinite flow from this input: the frame is unusable, never a result."""


def short_path(path: str | os.PathLike[str], limit: int = 120) -> str:
    """``path`` for an error message: as given, or its start and end around "..." when longer than ``limit``
    characters (an over-long path must not turn a one-line error into a screenful)."""
    text = os.fsdecode(path)
    if len(text) <= limit:
        return text
    keep = (limit - 3) // 2
    return f"{text[:keep]}...{text[-keep:]}"
