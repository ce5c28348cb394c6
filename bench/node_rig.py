"""The live node as its own process and a client beside it: what the node benches (node_latency,
security_latency, fuzz_node) share.

The node runs as ``python -m flow_node.ros.node`` (as ``ros2 run`` does) with the given ROS parameters and
names; the client is an rclpy node in a private context, spun by one single-threaded executor thread, that
publishes frames to the node's input and records the node's ~/flow messages (with their arrival time) and its
/diagnostics windows (key -> value, plus ``_message``).
"""

from __future__ import annotations

import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from typing import IO, Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import Image

NODE_COMMAND = (sys.executable, "-m", "flow_node.ros.node")
WARMING = "warming up the engine"  # the node's diagnostics message until its engine is warm


def wait(pred: Callable[[], Any], timeout: float) -> bool:
    """Poll ``pred`` every millisecond until it is true (True) or ``timeout`` s have passed (False)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.001)
    return False


def stop(proc: subprocess.Popen, timeout: float = 30.0) -> tuple[str | None, int | None]:
    """SIGINT ``proc`` (if it still runs) and collect it: (its stdout if piped, its exit code; None when it
    had to be killed after ``timeout`` s)."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
    try:
        out, _ = proc.communicate(timeout=timeout)
        return out, proc.returncode
    except subprocess.TimeoutExpired:
        proc.kill()
        out, _ = proc.communicate()
        return out, None


class NodeProcess:
    """A flow node process at ``ns``/``name`` and the client that feeds it (``pub``, message type
    ``input_type`` on ``input_topic``) and records ``flows`` [(perf_counter s, Image)] and ``diag`` (every
    diagnostics window of the node, oldest first) under ``lock``. Construction returns once the node has
    warmed up and both directions are matched (RuntimeError after 120 s)."""

    def __init__(self, ns: str, name: str, params: dict[str, str], client: str, client_ns: str | None = None,
                 input_type: type = Image, input_topic: str = "image", command: tuple[str, ...] = NODE_COMMAND,
                 log: IO[str] | None = None) -> None:
        self.name, self.flow_topic = name, f"{ns}/{name}/flow"
        self.ctx = Context()
        rclpy.init(context=self.ctx)
        self.client = Node(client, namespace=client_ns or "", context=self.ctx)
        self.pub = self.client.create_publisher(input_type, f"{ns}/{input_topic}", 10)
        self.lock = threading.Lock()
        self.flows: list[tuple[float, Image]] = []
        self.diag: list[dict[str, str]] = []
        self.client.create_subscription(Image, self.flow_topic, self._on_flow, 10)
        self.client.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 100)
        self.executor = SingleThreadedExecutor(context=self.ctx)  # as rclpy.spin in main()
        self.executor.add_node(self.client)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()
        ros_args = [a for k, v in params.items() for a in ("-p", f"{k}:={v}")]
        self.proc = subprocess.Popen(
            [*command, "--ros-args", *ros_args, "-r", f"__ns:={ns}", "-r", f"__node:={name}"],
            stdout=log or subprocess.DEVNULL, stderr=subprocess.STDOUT if log else subprocess.DEVNULL)
        if not wait(self.ready, 120.0):
            self.close()
            raise RuntimeError("the node process did not come up")

    def _on_flow(self, msg: Image) -> None:
        with self.lock:
            self.flows.append((time.perf_counter(), msg))

    def _on_diag(self, msg: DiagnosticArray) -> None:
        for st in msg.status:
            if st.name == f"{self.name}: optical flow":
                with self.lock:
                    self.diag.append({kv.key: kv.value for kv in st.values} | {"_message": st.message})

    def count(self) -> int:
        """Flows received so far."""
        with self.lock:
            return len(self.flows)

    def last(self) -> dict[str, str] | None:
        """The node's latest diagnostics window (None before the first)."""
        with self.lock:
            return self.diag[-1] if self.diag else None

    def ready(self) -> bool:
        """Warm-up done, the node subscribed to our input and our flow subscription matched."""
        last = self.last()
        return (last is not None and last["_message"] != WARMING and self.pub.get_subscription_count() > 0
                and self.client.count_publishers(self.flow_topic) > 0)

    def close(self) -> int | None:
        """Stop the node (SIGINT, killed after 30 s), then the client; the node's exit code (None if killed)."""
        _, code = stop(self.proc)
        self.executor.shutdown(timeout_sec=5.0)
        self.client.destroy_node()
        rclpy.try_shutdown(context=self.ctx)
        self.thread.join(timeout=5.0)
        return code
