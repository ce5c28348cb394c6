"""Exploration only (task smoothbags; not in the engine): realtime census with the L1 majoriser's DELTA
(census.CensusParams.delta, 0.2; below it the IRLS weight 1/sqrt(rho^2 + delta^2) is flat, i.e. the "L1" term
is quadratic) replaced, as tuneset.py otherwise.

    PYTHONPATH=$PWD DELTA=0.05 python .../delta.py NAMES [SCENES [SEEDS]]
"""

from __future__ import annotations

import os
import sys
from dataclasses import replace

from flow_node.core import refine

refine.CENSUS = replace(refine.CENSUS, delta=float(os.environ.get("DELTA", "0.2")))
sys.path.insert(0, os.path.dirname(__file__))
from tuneset import main  # noqa: E402

if __name__ == "__main__":
    main()
