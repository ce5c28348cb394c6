"""Shared benchmark helpers: where the data is, and the results files.

The peers live with the suite (bench/suite/methods.py); the Middlebury pairs are loaded by the suite
(bench/suite/data.py) and the paper protocol (bench/paper/protocol.py).
"""

from __future__ import annotations

import json
import os
import platform
import shlex
import sys
import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
DEFAULT_DATA = REPO.parent / "shared" / "data" / "middlebury"
SEQUENCES = ("Dimetrodon", "Grove2", "Grove3", "Hydrangea", "RubberWhale", "Urban2", "Urban3", "Venus")


def machine() -> dict[str, Any]:
    """Where a result was measured (for the JSON files)."""
    return {"python": platform.python_version(), "machine": platform.machine(), "cpus": os.cpu_count()}


def run_record(prog: str, argv: list[str] | None) -> dict[str, Any]:
    """The head of a result file: the command that made it (``python -m PROG ARGS``; ``argv`` None: this
    process's arguments), when it started (UTC), the machine and its load average (1, 5, 15 min) then."""
    args = sys.argv[1:] if argv is None else argv
    return {"command": f"python -m {prog} {shlex.join(args)}".strip(),
            "started": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "machine": machine(),
            "load_average_start": os.getloadavg()}


def md_table(header: Sequence[str], rows: Iterable[Sequence[str]], right: bool = False) -> list[str]:
    """A Markdown table's lines: ``header``, its rule (every column after the first right-aligned when
    ``right``) and one line per row of cells."""
    rule = "|---|" + ("---:|" if right else "---|") * (len(header) - 1)
    return ["| " + " | ".join(header) + " |", rule, *("| " + " | ".join(row) + " |" for row in rows)]


def write_json(path: Path, payload: dict[str, Any]) -> None:
    """``payload`` as indented JSON at ``path`` (its folder made)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(payload, indent=1, sort_keys=False) + "\n")


def wxh(text: str) -> tuple[int, int]:
    """``"WxH"`` (a command line's size) -> (W, H)."""
    w, h = (int(x) for x in text.lower().split("x"))
    return w, h


def write_result(stem: Path | None, payload: dict[str, Any], md: str) -> None:
    """Print a result's Markdown ``md``; unless ``stem`` is None, write it as ``stem``.md and ``payload`` as
    ``stem``.json (the folder made)."""
    print(md)
    if stem is not None:
        write_json(stem.with_suffix(".json"), payload)
        stem.with_suffix(".md").write_text(md)
