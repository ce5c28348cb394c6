"""The benchmarks, each run as an executable (``python -m bench.<name>``): like the product's executables,
they let idle numba threads sleep (flow_node/process.py), so that what they measure is what users run."""

from flow_node.process import passive_thread_waits

passive_thread_waits()
