"""Test-wide setup: isolate DDS traffic to this machine and this run, keep numba's cache in the venv."""

import os
import random

import numpy as np
import pytest

from flow_node.process import passive_thread_waits

# Set before rclpy is imported anywhere: localhost-only discovery and a per-run domain id, so parallel
# runs and other ROS processes on the machine never see our topics.
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
os.environ.setdefault("ROS_DOMAIN_ID", str(random.SystemRandom().randint(1, 100)))
os.environ.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
passive_thread_waits()  # idle numba threads sleep, as in the executables: the test process is one


@pytest.fixture
def median_sizes(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The median filter's sizes after each warp from now on, in order (refine.warp_median: the plain median or,
    where the config weighs it, the weighted one; the filter itself still runs)."""
    from flow_node.core import refine

    sizes: list[int] = []
    real = refine.warp_median

    def spy(v: np.ndarray, i0: np.ndarray, size: int, *args: object, **kwargs: object) -> np.ndarray:
        sizes.append(size)
        return real(v, i0, size, *args, **kwargs)

    monkeypatch.setattr(refine, "warp_median", spy)
    return sizes
