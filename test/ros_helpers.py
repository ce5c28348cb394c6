"""Real-DDS test harness: a FlowNode and a test node in one rclpy context, spun by an executor thread.

Nothing is mocked: frames go out through a real publisher, the node receives them over DDS (the domain and
discovery range are isolated by conftest.py), and outputs are collected by real subscriptions.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import rclpy
import small_frames
from diagnostic_msgs.msg import DiagnosticArray
from frame_messages import FRAME_ID, GT, I0, I1, H, W, image, mono8, set_stamp
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState
from rclpy.context import Context
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import CompressedImage, Image

from flow_node.ros.node import FlowNode

# the test pair and the message builders live in frame_messages.py (no rclpy); re-exported for the DDS tests
__all__ = ["FAST", "FRAME_ID", "GT", "H", "I0", "I1", "W", "Harness", "call", "image", "mono8", "set_stamp",
           "wait_for"]

FAST = small_frames.PARAMS  # fast and deterministic on these 80x60 frames


def wait_for(pred: Callable[[], Any], timeout: float = 10.0, what: str = "condition") -> Any:
    """Poll ``pred`` until truthy; fails the test with ``what`` after ``timeout`` s."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = pred()
        if value:
            return value
        time.sleep(0.01)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def call(cli: Any, request: Any, timeout: float = 10.0) -> Any:
    """Call a service through a client whose node is spun by the harness executor; returns the response."""
    future = cli.call_async(request)
    return wait_for(lambda: future.done() and future.result(), timeout, f"service {cli.srv_name}")


class Harness:
    """FlowNode ``name`` in namespace ``ns`` with parameter overrides, plus publisher and collectors."""

    def __init__(self, ns: str, params: dict[str, Any] | None = None, name: str = "flow_node",
                 color: bool = True, executor: type[Executor] = SingleThreadedExecutor) -> None:
        self.ctx = Context()
        rclpy.init(context=self.ctx)
        overrides = [Parameter(k, value=v) for k, v in {**FAST, **(params or {})}.items()]
        self.node = FlowNode(name, namespace=ns, parameter_overrides=overrides, context=self.ctx)
        self.full_name = f"{ns}/{name}"
        self.client = Node("test_client", namespace=ns, context=self.ctx)
        self.pub = self.client.create_publisher(Image, f"{ns}/image", 10)
        self.pub_compressed = self.client.create_publisher(CompressedImage, f"{ns}/image/compressed", 10)
        self.cond = threading.Condition()
        self.received: dict[str, list[tuple[float, Any]]] = {"flow": [], "magnitude": [], "flow_color": [],
                                                             "diagnostics": []}
        topics = ["flow", "magnitude"] + (["flow_color"] if color else [])
        self._subs = [self.client.create_subscription(Image, f"{self.full_name}/{t}", self._collector(t), 10)
                      for t in topics]
        self._subs.append(self.client.create_subscription(DiagnosticArray, "/diagnostics",
                                                          self._diag_collector, 10))
        # by default the executor ``rclpy.spin`` (the node's main()) uses; rclpy's MultiThreadedExecutor keeps
        # polling while frames flood in and starves the node's worker of the GIL (docs/node.md)
        self.executor = executor(context=self.ctx)
        self.executor.add_node(self.node)
        self.executor.add_node(self.client)
        self._spin = threading.Thread(target=self.executor.spin, daemon=True)
        self._spin.start()
        if self.node.managed:  # brought to active by this test, as a lifecycle manager does
            for transition in (Transition.TRANSITION_CONFIGURE, Transition.TRANSITION_ACTIVATE):
                assert self.change_state(transition), f"lifecycle transition {transition} failed"
        wait_for(lambda: self.node.ready, 30.0, "engine warm-up")
        wait_for(lambda: self.pub.get_subscription_count() > 0 or self.pub_compressed.get_subscription_count() > 0,
                 10.0, "node subscription matched")
        wait_for(lambda: self.subscribers("flow") > 0, 10.0, "flow subscription matched")

    def _collector(self, topic: str) -> Callable[[Any], None]:
        def cb(msg: Any) -> None:
            with self.cond:
                self.received[topic].append((time.monotonic(), msg))
                self.cond.notify_all()
        return cb

    def _diag_collector(self, msg: DiagnosticArray) -> None:
        for st in msg.status:
            if st.name == f"{self.node.get_name()}: optical flow":
                with self.cond:
                    self.received["diagnostics"].append((time.monotonic(), st))

    def count(self, topic: str) -> int:
        with self.cond:
            return len(self.received[topic])

    def last(self, topic: str) -> Any:
        with self.cond:
            return self.received[topic][-1][1]

    @property
    def totals(self) -> Any:
        return self.node.stats.totals

    def subscribers(self, output: str) -> int:
        """Subscriptions matched to the node's output ``~/<output>`` (0 when it has none)."""
        return self.node.state().subscribers.get(output, 0)

    def send(self, msg: Image | CompressedImage, until: Callable[[], Any], what: str, timeout: float = 10.0) -> Any:
        """Publish ``msg`` until ``until()``; re-published after a second only if the node did not receive it
        (the input QoS is best effort), never twice once received (that would pair a frame with itself)."""
        pub = self.pub_compressed if isinstance(msg, CompressedImage) else self.pub
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            received = self.totals.received
            pub.publish(msg)
            try:
                return wait_for(until, min(1.0, max(end - time.monotonic(), 0.01)), what)
            except AssertionError:
                if self.totals.received > received:  # it arrived and is being solved: just wait
                    return wait_for(until, max(end - time.monotonic(), 0.01), what)
        raise AssertionError(f"timed out after {timeout} s waiting for {what}")

    def send_frame(self, msg: Image | CompressedImage, timeout: float = 10.0) -> None:
        """Publish one frame and wait until the node has dealt with it (processed, rejected or failed)."""
        t = self.totals
        before = t.processed + t.rejected + t.errors
        self.send(msg, lambda: t.processed + t.rejected + t.errors > before, "the node to handle a frame", timeout)

    def send_pair(self, f0: Image, f1: Image) -> Any:
        """Send two frames; returns the flow message published for the second."""
        self.send_frame(f0)
        n = self.count("flow")
        self.send_frame(f1)
        wait_for(lambda: self.count("flow") > n, 10.0, "flow output")
        return self.last("flow")

    def change_state(self, transition: int) -> bool:
        """A lifecycle transition (lifecycle_msgs/Transition id) through the node's ~/change_state service."""
        cli = self.client.create_client(ChangeState, f"{self.full_name}/change_state")
        try:
            assert cli.wait_for_service(timeout_sec=5.0)
            return bool(call(cli, ChangeState.Request(transition=Transition(id=transition)), 60.0).success)
        finally:
            self.client.destroy_client(cli)

    def set_params(self, **values: Any) -> list[Any]:
        """Set parameters through the node's SetParameters service (one request, per-parameter results)."""
        from rcl_interfaces.srv import SetParameters

        cli = self.client.create_client(SetParameters, f"{self.full_name}/set_parameters")
        try:
            assert cli.wait_for_service(timeout_sec=5.0)
            req = SetParameters.Request(parameters=[Parameter(k, value=v).to_parameter_msg()
                                                    for k, v in values.items()])
            return call(cli, req).results
        finally:
            self.client.destroy_client(cli)

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=5.0)
        self.node.destroy_node()
        self.client.destroy_node()
        rclpy.try_shutdown(context=self.ctx)
        self._spin.join(timeout=5.0)
