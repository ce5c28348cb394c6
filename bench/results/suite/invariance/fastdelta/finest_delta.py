"""Exploration only (task fastdelta; not in the engine): ``census_delta`` on the finest solved level only (the
coarser levels keep CENSUS.delta 0.2), by wrapping refine.level_census; then runs ``bench.suite`` or, with
``--tuneset``, tuneset.py with the remaining arguments.

    PYTHONPATH=$PWD python bench/results/suite/invariance/fastdelta/finest_delta.py [--tuneset] ARGS...
"""

from __future__ import annotations

import os
import runpy
import sys
from dataclasses import replace

from flow_node.core import refine
from flow_node.core.census import CENSUS

_level_census = refine.level_census


def finest_only(cfg, width, eps_floor=0.0, contrast=float("inf"), finest=False):  # type: ignore[no-untyped-def]
    """level_census with DELTA cfg.census_delta on the finest solved level, CENSUS.delta elsewhere."""
    params = _level_census(cfg, width, eps_floor, contrast, finest)
    return params if finest else replace(params, delta=CENSUS.delta)


refine.level_census = finest_only
if __name__ == "__main__":
    if sys.argv[1] == "--tuneset":
        sys.argv = [os.path.join(os.path.dirname(__file__), "tuneset.py")] + sys.argv[2:]
        runpy.run_path(sys.argv[0], run_name="__main__")
    else:
        sys.argv = ["bench.suite"] + sys.argv[1:]
        runpy.run_module("bench.suite", run_name="__main__")
