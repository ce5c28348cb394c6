"""Tune set for task cschedule (issue 25): fastdelta's tuneset.py (smoothbags' rendered scenes, 128x96, seeds
101-108, rendered as ``flow_bag synth`` renders the bundled bags) for any preset, scored against that preset's
census as it is today (its own census fields; fastdelta's ``census`` reset DELTA and alpha to the old defaults).

    PYTHONPATH=$PWD python bench/results/suite/invariance/cschedule/tuneset.py PRESET NAMES [SCENES [SEEDS]]

NAMES as in fastdelta/tuneset.py: ``grey`` (PRESET, grey values), ``census`` (PRESET census),
``key=value+key=value`` (that census with FlowConfig changes).
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

from flow_node.core.config import FlowConfig

spec = importlib.util.spec_from_file_location("fastdelta_tuneset", Path(__file__).parents[1] / "fastdelta/tuneset.py")
assert spec is not None and spec.loader is not None
tuneset = importlib.util.module_from_spec(spec)
spec.loader.exec_module(tuneset)
tuneset.FAST = FlowConfig.preset(sys.argv[1]).replace(threads=1)  # config() reads these two at call time
tuneset.CEN = tuneset.FAST.replace(photometric="census")
sys.argv = [sys.argv[0], *sys.argv[2:]]
tuneset.main()
