"""The broad accuracy suite (issue 11): every preset and the peers on Middlebury, large motions, exactly
rendered synthetic regimes and the bundled bags, in one run.

    .venv-bench/bin/python -m bench.suite                 # full run, report seeds -> bench/results/suite/suite.*
    .venv-bench/bin/python -m bench.suite --quick         # a 1-3 minute loop (DIS peers only)

As a library (tuning loops)::

    from bench.suite import run_suite
    res = run_suite({"mine": FlowConfig.preset("realtime").replace(alpha=0.03)}, ["fine_320"], "tune", quick=True)
    res["regimes"]["fine_320"]["methods"]["mine"]["aee"], ...["time_vs_dis_medium"]
"""

from .regimes import REGIMES
from .runner import run_suite

__all__ = ["REGIMES", "run_suite"]
