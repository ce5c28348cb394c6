"""The node's lifecycle (an rclpy managed node): who drives it, and how a transition's work is run and reported.

    unconfigured --configure--> inactive --activate--> active --deactivate--> inactive --cleanup--> unconfigured
    unconfigured | inactive | active --shutdown--> finalized         (main() then exits with code 0)

What each transition does is in :class:`~flow_node.ros.node.FlowNode` and docs/node.md ("Managed (lifecycle)
node"). With the parameter ``managed`` false (the default) the node makes configure and activate itself when
it is constructed, so ``ros2 run`` and code that builds a ``FlowNode`` get a running node as before; with
``managed`` true it waits in unconfigured for a lifecycle manager (``ros2 lifecycle set``, the launch file's
ChangeState events, nav2's lifecycle manager). The lifecycle services exist either way.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from lifecycle_msgs.srv import ChangeState
from rclpy._rclpy_pybind11 import RCLError
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn
from rclpy.qos import QoSProfile

from ..core.errors import FlowError
from .startup import rcl_error_line

SUCCESS, FAILURE, ERROR = (TransitionCallbackReturn.SUCCESS, TransitionCallbackReturn.FAILURE,
                           TransitionCallbackReturn.ERROR)


def state_label(node: LifecycleNode) -> str:
    """The node's lifecycle state: ``unconfigured``, ``inactive``, ``active``, ``finalized`` or a transition
    state (``configuring``, ...). rclpy 7 (Jazzy) has no public getter: its state machine is read directly."""
    return str(node._state_machine.current_state[1])  # noqa: SLF001 -- see the docstring


@dataclass(frozen=True)
class NodeState:
    """What the node is doing, as one read-only snapshot (:meth:`FlowNode.state`), for users and tests."""

    lifecycle: str  # state_label(): unconfigured, inactive, active, finalized or a transition
    failure: str  # TransitionLog.reason of the last transition: '' after a success
    ready: bool  # configured and warmed up
    input_topic: str | None  # the image (or compressed image) subscription's topic; None unless active
    input_qos: QoSProfile | None  # its QoS, after the qos_overrides parameters
    camera_info_topic: str | None  # the camera_info subscription's topic; None unless active
    camera_info_received: bool  # a camera_info message arrived since configure
    subscribers: dict[str, int]  # output name (``~/<name>``) -> matched subscriptions; {} unless configured
    frame_waiting: bool  # a received frame waits for the worker
    secured: bool | None  # the start-up security check (security.SecurityCheck.secured)
    mask: np.ndarray | None = None  # the validity mask in effect (FlowStream.mask: input size, bool); None: all valid


@dataclass
class TransitionLog:
    """How the last transition ended: the exception and name of the last one, if it did not succeed."""

    logger: RcutilsLogger
    log_failures: bool  # a managed node logs them; an unmanaged one raises them from its constructor instead
    failure: Exception | None = None
    failed: str = ""  # the transition that raised it

    def run(self, name: str, step: Callable[[], None]) -> TransitionCallbackReturn:
        """Run ``step``, the work of transition ``name``: SUCCESS if it returns; FAILURE if it raises a
        FlowError (a reason: invalid parameters, a failed warm-up; the node stays in its state); ERROR for
        anything else (rclpy then runs on_error). Failures and errors are logged when :attr:`log_failures`,
        since rclpy itself only answers ``success: false`` (``ros2 lifecycle set``: "Transitioning failed")."""
        self.failure, self.failed = None, name
        try:
            step()
        except Exception as exc:  # rclpy would swallow it without a word
            self.failure = exc
            if self.log_failures:
                self.logger.error(self.reason)
            return FAILURE if isinstance(exc, FlowError) else ERROR
        return SUCCESS

    @property
    def reason(self) -> str:
        """``<transition> failed: <reason>`` on one line, for the log and diagnostics; '' after a success."""
        exc = self.failure
        if exc is None:
            return ""
        return f"{self.failed} failed: " + (str(exc) if isinstance(exc, FlowError) else f"{type(exc).__name__}: {exc}")


def guard_change_state(node: LifecycleNode, logger: RcutilsLogger) -> None:
    """Answer ``success: false`` to a ChangeState request for a transition the current state does not have
    (e.g. activate while unconfigured), as rclcpp does. rclpy 7.1.6 (the Jazzy wheels) lets rcl's RCLError
    escape the service callback, which ends the node's spin: ros2/rclpy#1209, fixed upstream by #1319. The
    ``ros2 lifecycle set`` CLI checks first, but a service call or a launch ChangeState event does not."""
    service = node._service_change_state  # noqa: SLF001 -- rclpy creates it; no public handle
    answer = service.callback

    def guarded(request: ChangeState.Request, response: ChangeState.Response) -> ChangeState.Response:
        try:
            return answer(request, response)
        except RCLError as exc:
            logger.warning(f"transition {request.transition.id} {request.transition.label!r} refused: "
                           f"{rcl_error_line(exc)}")
            response.success = False
            return response

    service.callback = guarded


def bring_up(node: LifecycleNode, log: TransitionLog) -> None:
    """Configure and activate ``node`` (an unmanaged node, from its constructor); raises the exception of the
    transition that failed (main() reports a FlowError as "cannot start: ...", exit code 1)."""
    for trigger in (node.trigger_configure, node.trigger_activate):
        if trigger() != SUCCESS:
            raise log.failure if log.failure is not None else FlowError(f"{trigger.__name__} failed")
