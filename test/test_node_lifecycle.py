"""The managed (lifecycle) node over real DDS: ``managed: true`` waits unconfigured; configure, activate,
deactivate, cleanup and shutdown through its lifecycle services (lifecycle_msgs ChangeState / GetState, as
``ros2 lifecycle set`` and launch call them); inactive it publishes no flow and answers parameter services;
a configure with invalid parameters fails with the reason and can be retried; unmanaged it is active at once."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter, parameter_value_to_python
from ros_helpers import FAST, GT, I0, I1, call, image, mono8, wait_for
from sensor_msgs.msg import Image

from flow_node.core.metrics import aee
from flow_node.pipeline.codec import image_to_array
from flow_node.pipeline.derived import MOTION_TOPICS
from flow_node.ros import lifecycle
from flow_node.ros.node import FlowNode

pytestmark = pytest.mark.ros  # rclpy over DDS: a node or a publisher in this process, or a node process

NS, NAME = "/t_life", "flow_life"
FULL = f"{NS}/{NAME}"


class Manager:
    """A lifecycle manager and camera in this process: calls the node's services, publishes frames, collects
    its flow and diagnostics; spun by its own executor thread."""

    def __init__(self) -> None:
        self.ctx = Context()
        rclpy.init(context=self.ctx)
        self.node = Node("life_manager", context=self.ctx)
        self.flows: list[Image] = []
        self.diags: list[DiagnosticStatus] = []
        self.node.create_subscription(Image, f"{FULL}/flow", self.flows.append, 10)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", lambda m: self.diags.extend(
            s for s in m.status if s.name == f"{NAME}: optical flow"), 10)
        self.pub = self.node.create_publisher(Image, f"{NS}/image", 10)
        self.executor = SingleThreadedExecutor(context=self.ctx)
        self.executor.add_node(self.node)
        self._spin = threading.Thread(target=self.executor.spin, daemon=True)
        self._spin.start()
        self.stamp = 1_000

    def service(self, kind: Any, name: str, request: Any, timeout: float = 60.0) -> Any:
        cli = self.node.create_client(kind, f"{FULL}/{name}")
        try:
            assert cli.wait_for_service(timeout_sec=30.0), f"no service {FULL}/{name}"
            return call(cli, request, timeout)
        finally:
            self.node.destroy_client(cli)

    def state(self) -> str:
        return self.service(GetState, "get_state", GetState.Request()).current_state.label

    def change(self, transition: int) -> bool:
        return self.service(ChangeState, "change_state", ChangeState.Request(transition=Transition(id=transition))
                            ).success

    def param(self, name: str) -> Any:
        (value,) = self.service(GetParameters, "get_parameters", GetParameters.Request(names=[name])).values
        return parameter_value_to_python(value)

    def set_param(self, name: str, value: Any) -> bool:
        req = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
        (result,) = self.service(SetParameters, "set_parameters", req).results
        return bool(result.successful)

    def frames(self, seconds: float) -> None:
        """I0 and I1 in turn, a frame every 0.2 s (best effort: a frame may not arrive, so several pairs)."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.pub.publish(image(mono8(I0 if self.stamp % 2 == 0 else I1), "mono8", self.stamp))
            self.stamp += 1
            time.sleep(0.2)

    def flow_after(self, stamp: int, timeout: float = 30.0) -> Image:
        """Frames until a flow for a frame newer than ``stamp`` arrives (I1 at odd stamps: the known motion)."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            got = [f for f in list(self.flows) if f.header.stamp.nanosec > stamp and f.header.stamp.nanosec % 2]
            if got:
                return got[0]
            self.frames(0.4)
        raise AssertionError(f"no flow within {timeout} s")

    def status(self, state: str, where: Callable[[dict[str, str]], bool] = lambda values: True) -> DiagnosticStatus:
        """The latest diagnostics in lifecycle ``state`` whose values satisfy ``where``, waiting for one."""
        def found() -> DiagnosticStatus | None:
            for s in reversed(list(self.diags)):
                values = {kv.key: kv.value for kv in s.values}
                if values["lifecycle state"] == state and where(values):
                    return s
            return None
        return wait_for(found, 10.0, f"diagnostics saying {state}")

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=5.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.ctx)
        self._spin.join(timeout=5.0)


@pytest.fixture
def managed_node(tmp_path: Path) -> Iterator[tuple[subprocess.Popen[str], Manager]]:
    """``python -m flow_node.ros.node`` (what ``ros2 run`` starts) with ``managed:=true``, and a manager."""
    params = [a for k, v in {**FAST, "managed": True, "diagnostics_period": 0.3}.items()
              for a in ("-p", f"{k}:={v}")]
    proc = subprocess.Popen([sys.executable, "-m", "flow_node.ros.node", "--ros-args", "-r", f"__ns:={NS}",
                             "-r", f"__node:={NAME}", *params], env=dict(os.environ), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, cwd=tmp_path)
    manager = Manager()
    try:
        yield proc, manager
    finally:
        manager.close()
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            proc.communicate(timeout=20)


def test_managed_node_through_its_lifecycle_services(managed_node: tuple[subprocess.Popen[str], Manager]) -> None:
    proc, m = managed_node
    assert m.state() == "unconfigured"
    assert m.param("preset") == "realtime" and m.param("managed") is True
    assert m.status("unconfigured").message == "unconfigured: waiting for configure (lifecycle)"
    assert m.node.count_publishers(f"{FULL}/flow") == 0  # nothing exists before configure

    assert m.change(Transition.TRANSITION_CONFIGURE)
    assert m.state() == "inactive"
    wait_for(lambda: m.node.count_publishers(f"{FULL}/flow") == 1, 10.0, "the flow publisher (configured)")
    # inactive: the publisher exists, the input is not subscribed, a camera's frames give no flow
    m.frames(2.0)
    assert m.pub.get_subscription_count() == 0 and not m.flows
    # ... and the parameter services answer
    assert m.set_param("iterations", 25) and m.param("iterations") == 25
    assert not m.set_param("alpha", -1.0)  # still validated
    status = m.status("inactive")
    assert (status.level, status.message) == (DiagnosticStatus.OK,
                                              "inactive: frames are not processed until activated (lifecycle)")

    assert m.change(Transition.TRANSITION_ACTIVATE)
    assert m.state() == "active"
    wait_for(lambda: m.pub.get_subscription_count() > 0, 10.0, "the node's image subscription")
    flow = m.flow_after(0)
    assert aee(image_to_array(flow), GT) < 0.25
    m.status("active", lambda values: values["frames published"] != "0")  # diagnostics count the flow

    assert m.change(Transition.TRANSITION_DEACTIVATE)
    assert m.state() == "inactive"
    wait_for(lambda: m.pub.get_subscription_count() == 0, 10.0, "the node to unsubscribe")
    time.sleep(0.5)  # a flow already on the wire when deactivate was answered
    before = len(m.flows)
    m.frames(2.0)
    assert len(m.flows) == before, "an inactive node published flow"
    assert m.param("iterations") == 25  # kept

    assert m.change(Transition.TRANSITION_ACTIVATE)  # the engine was kept: no warm-up again
    last = m.stamp
    assert aee(image_to_array(m.flow_after(last)), GT) < 0.25

    for transition, state in ((Transition.TRANSITION_DEACTIVATE, "inactive"),
                              (Transition.TRANSITION_CLEANUP, "unconfigured")):
        assert m.change(transition) and m.state() == state
    wait_for(lambda: m.node.count_publishers(f"{FULL}/flow") == 0, 10.0, "the publishers gone (cleanup)")
    assert m.param("iterations") == 25
    assert not m.change(Transition.TRANSITION_ACTIVATE)  # not from unconfigured: refused, the node lives on

    assert m.change(Transition.TRANSITION_UNCONFIGURED_SHUTDOWN)
    out, _ = proc.communicate(timeout=20)  # finalized: main() returns
    assert proc.returncode == 0, out
    for line in ("configured: input /t_life/image", "engine warm-up (numpy)", "active: subscribed to /t_life/image",
                 "inactive: frames are not processed", "finalized"):
        assert line in out, out
    assert "Traceback" not in out and "[ERROR]" not in out, out


@pytest.fixture
def context() -> Iterator[Context]:
    ctx = Context()
    rclpy.init(context=ctx)
    yield ctx
    rclpy.try_shutdown(context=ctx)


def test_invalid_parameters_fail_configure_with_the_reason_and_a_fixed_one_succeeds(context: Context) -> None:
    params = {**FAST, "managed": True, "model": "l1_tv_l2", "alpha1": 0.0}
    node = FlowNode("flow_life_bad", parameter_overrides=[Parameter(k, value=v) for k, v in params.items()],
                    context=context)
    try:
        assert lifecycle.state_label(node) == "unconfigured"  # constructed: invalid values wait for configure
        assert node.trigger_configure() == lifecycle.FAILURE
        assert lifecycle.state_label(node) == "unconfigured" and not node.ready
        assert node.state().failure.startswith("configure failed: alpha1 must be > 0 for model 'l1_tv_l2'")
        assert node.set_parameters([Parameter("alpha1", value=0.02)])[0].successful
        assert node.trigger_configure() == lifecycle.SUCCESS and node.state().failure == ""
        assert lifecycle.state_label(node) == "inactive" and node.settings.config.alpha1 == 0.02
        assert node.ready  # managed: configure returned after the warm-up
        assert node.trigger_shutdown() == lifecycle.SUCCESS and node.finalized.done()
    finally:
        node.destroy_node()


def test_unmanaged_node_is_active_once_constructed(context: Context) -> None:
    node = FlowNode("flow_life_plain", parameter_overrides=[Parameter(k, value=v) for k, v in FAST.items()],
                    context=context)
    try:
        assert lifecycle.state_label(node) == "active" and not node.managed
        assert node.state().input_topic == "/image"
        assert node.trigger_deactivate() == lifecycle.SUCCESS and node.state().input_topic is None
        assert node.trigger_cleanup() == lifecycle.SUCCESS and node.state().subscribers == {} and not node.ready
        # configured again: the publishers' QoS override parameters exist already and are reused
        assert node.trigger_configure() == lifecycle.SUCCESS and node.trigger_activate() == lifecycle.SUCCESS
        state = node.state()
        assert state.input_topic == "/image" and set(state.subscribers) == {
            "flow", "magnitude", "flow_color", "confidence", "flow_pair", "camera_info", *MOTION_TOPICS}
    finally:
        node.destroy_node()
