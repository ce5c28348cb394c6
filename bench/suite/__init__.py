"""The broad accuracy suite (issue 11): ``python -m bench.suite``, or ``run_suite`` as a library for tuning
loops (docs/suite.md)."""

from .regimes import REGIMES
from .runner import run_suite

__all__ = ["REGIMES", "run_suite"]
