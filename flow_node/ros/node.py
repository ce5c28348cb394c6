"""The flow_node ROS 2 node: a managed (lifecycle) node wiring topics, parameters, a service and diagnostics
to the pipeline.

Lifecycle (flow_node/ros/lifecycle.py, docs/node.md): configure validates the parameters, builds the engine,
creates the (lifecycle) publishers and the worker, which warms the engine up; activate enables the publishers
and subscribes; deactivate unsubscribes and silences the publishers; cleanup drops the engine and its state.
Parameters, ``~/reset``, the lifecycle services and ``/diagnostics`` live in every state. Unless the parameter
``managed`` is true the constructor makes configure and activate itself.

Threading (flow_node/ros/worker.py): the subscription callback (executor) only drops the message into a one-slot
mailbox (latest wins; a replaced message is counted as dropped) and returns. The worker thread takes the newest
message, decodes it, runs :class:`~flow_node.pipeline.stream.FlowStream` and publishes, the derived ``~/motion/*``
outputs through flow_node/ros/motion_outputs.py (only those subscribed). The executor thus never runs a solve,
so parameter services, ``~/reset`` and diagnostics answer while a frame is being solved.
"""

from __future__ import annotations

import sys
import threading
import time
from typing import Any

import rclpy
from rcl_interfaces.msg import SetParametersResult
from rclpy._rclpy_pybind11 import RCLError
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.lifecycle import LifecycleNode, LifecyclePublisher, LifecycleState, TransitionCallbackReturn
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, qos_profile_sensor_data
from rclpy.qos_overriding_options import QoSOverridingOptions
from rclpy.subscription import Subscription
from rclpy.task import Future
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, TimeReference
from std_srvs.srv import Trigger

from .. import middleware
from ..core.backends import fallback_warning
from ..core.errors import ConfigError, FlowError, InputError
from ..pipeline.codec import decode
from ..pipeline.derived import fits_for, warm_fits
from ..pipeline.stream import FlowStream, StreamSettings
from ..process import defer_kernel_bitcode, keep_freed_memory, passive_thread_waits
from . import camera_info, diagnostics, lifecycle, security, startup
from .mask_input import MaskInput
from .messages import descriptor, executor_advice, publish_outputs, stamp_ns
from .motion_outputs import MOTION_TYPES, MotionOutputs
from .params import declared_defaults, expand_preset, motion_from_values, param_specs, settings_from_values
from .worker import FrameWorker

_OUTPUTS = (("flow", Image), ("magnitude", Image), ("flow_color", Image), ("confidence", Image),
            ("flow_pair", TimeReference), ("camera_info", CameraInfo), *MOTION_TYPES.items())


class FlowNode(LifecycleNode):
    """Optical flow between consecutive frames of ``image``; see docs/node.md for the interface."""

    def __init__(self, node_name: str = "flow_node", **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self._specs = {s.name: s for s in param_specs()}
        self._declare_parameters()
        self._managed: bool = self.get_parameter("managed").value
        self._transitions = lifecycle.TransitionLog(self.get_logger(), log_failures=self._managed)
        lifecycle.guard_change_state(self, self.get_logger())
        self.finalized = Future()  # done after the shutdown transition: main() then exits
        self._stats = diagnostics.NodeStats()
        self._stream: FlowStream | None = None
        self._worker: FrameWorker | None = None
        self._motion: MotionOutputs | None = None  # the derived outputs (~/motion/*), between configure and cleanup
        self._pubs: dict[str, LifecyclePublisher] = {}
        self._sub: Subscription | None = None
        self._sub_info: Subscription | None = None
        self._mask = MaskInput(self)  # the validity mask: mask_file, ~/mask
        self._gate = threading.Lock()  # the worker publishes holding it; deactivate closes it holding it
        self._active = False
        self._resolution = "none yet"
        self._frame_id = ""
        self._executor_checked = False
        self._camera_info: CameraInfo | None = None
        self._backend_warning: str | None = None
        self._pub_diag = self.create_publisher(diagnostics.DiagnosticArray, "/diagnostics", 10)
        self._srv_reset = self.create_service(Trigger, "~/reset", self._on_reset)
        self.add_pre_set_parameters_callback(self._expand_preset)
        self.add_on_set_parameters_callback(self._validate)
        self.add_post_set_parameters_callback(self._apply)
        self._diag_timer = self.create_timer(self.get_parameter("diagnostics_period").value, self._publish_diagnostics)
        self._security = security.check_and_log(self)  # warns when SROS2 is asked for but not in effect
        if not self._managed:  # plain start-up: configure and activate now (raises what failed)
            lifecycle.bring_up(self, self._transitions)

    # ------------------------------------------------------------------------------------------ lifecycle
    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        return self._transitions.run("configure", self._configure)

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        return self._transitions.run("activate", lambda: self._activate(state))

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        return self._transitions.run("deactivate", lambda: self._deactivate(state))

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        return self._transitions.run("cleanup", self._drop_engine)

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        result = self._transitions.run("shutdown", self._teardown)
        self.get_logger().info("finalized")
        self.finalized.set_result(True)
        return result

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        """After a transition raised: everything dropped, back to unconfigured (the failure stays reported)."""
        self._teardown()
        return lifecycle.SUCCESS

    def _configure(self) -> None:
        """Parameters validated as a whole, engine built, output publishers created (silent until active),
        worker created; a managed node also waits for the warm-up here (an unmanaged one warms up on the
        worker once active, while the executor answers parameter services)."""
        settings = settings_from_values(self._values())  # ConfigError: FAILURE, stays unconfigured
        self._motion = MotionOutputs(motion_from_values(self._values()))
        stream = FlowStream(settings)
        self._mask.configure(stream, self.get_parameter("mask_file").value)
        self._stats, self._stream, self._camera_info = diagnostics.NodeStats(), stream, None
        self._backend_warning = fallback_warning(settings.config.backend, stream.backend)
        overrides = QoSOverridingOptions.with_default_policies()
        self._pubs = {name: self.create_lifecycle_publisher(kind, f"~/{name}", 1, qos_overriding_options=overrides)
                      for name, kind in _OUTPUTS}
        self.get_logger().info(f"configured: input {self._image_topic()}; model {settings.config.model}, "
                               f"backend {stream.backend}; {middleware.middleware_line()}")
        if self._backend_warning:
            self.get_logger().warning(self._backend_warning)
        warmup = self._warmup if self.get_parameter("warmup").value else None
        self._worker = FrameWorker(f"{self.get_name()}_worker", self._handle, self._frame_failed, warmup)
        if self._managed:
            self._worker.start()
            self._worker.wait_ready()
            if self._worker.warmup_error:
                reason = f"engine warm-up failed: {self._worker.warmup_error}"
                self._drop_engine()
                raise FlowError(reason)

    def _activate(self, state: LifecycleState) -> None:
        """Publishers enabled, then the subscriptions created; the worker started if it was not."""
        assert self._worker is not None  # configured
        super().on_activate(state)  # enables the lifecycle publishers
        with self._gate:
            self._active = True
        qos = QoSProfile(**{k: getattr(qos_profile_sensor_data, k) for k in ("reliability", "durability",
                                                                           "history")}, depth=1)
        overrides = QoSOverridingOptions.with_default_policies()
        compressed = self.get_parameter("use_compressed").value
        kind, topic = (CompressedImage, self._image_topic()) if compressed else (Image, "image")
        self._sub = self.create_subscription(kind, topic, self._on_image, qos, qos_overriding_options=overrides)
        self._sub_info = self.create_subscription(
            CameraInfo, camera_info.camera_info_topic(self.resolve_topic_name("image")), self._on_camera_info, qos)
        self._mask.open(self._stream)
        self.get_logger().info(f"active: subscribed to {self._sub.topic_name}")
        self._worker.start()  # an unmanaged node warms up now; the warm-up line comes last (tools wait for it)

    def _deactivate(self, state: LifecycleState) -> None:
        """Unsubscribed, publishers silenced, a waiting frame dropped; parameters and engine kept. The next
        frame after activate starts a new pair (the one before may be long gone)."""
        self._close_input()
        super().on_deactivate(state)  # disables the lifecycle publishers
        if self._stream is not None:
            self._stream.reset("node was inactive")
        self.get_logger().info("inactive: frames are not processed until activated")

    def _close_input(self) -> None:
        for sub in (self._sub, self._sub_info):
            if sub is not None:
                self.destroy_subscription(sub)
        self._sub = self._sub_info = None
        self._mask.close()
        with self._gate:  # waits for a publish in progress; a solve in progress publishes nothing
            self._active = False
        if self._worker is not None and self._worker.mailbox.clear():
            self._stats.dropped()

    def _drop_engine(self) -> None:
        """Worker stopped (after the frame it is solving), publishers destroyed, engine and state dropped."""
        if self._worker is not None:
            self._worker.stop()
        for pub in self._pubs.values():
            self.destroy_lifecycle_publisher(pub)
        self._worker, self._pubs, self._stream, self._camera_info, self._motion = None, {}, None, None, None
        self._resolution = "none yet"

    def _teardown(self) -> None:
        self._close_input()
        self._drop_engine()

    def _image_topic(self) -> str:
        image = self.resolve_topic_name("image")
        return image + "/compressed" if self.get_parameter("use_compressed").value else image

    @property
    def managed(self) -> bool:
        return self._managed

    @property
    def stats(self) -> diagnostics.NodeStats:
        """The counters since the last configure (totals, solve_max, last_reset, last_rejection, last output);
        for reading: the node records into it."""
        return self._stats

    def state(self) -> lifecycle.NodeState:
        """A snapshot of the lifecycle state, subscriptions, matched outputs and worker (lifecycle.NodeState)."""
        sub, info, worker = self._sub, self._sub_info, self._worker
        return lifecycle.NodeState(
            lifecycle.state_label(self), self._transitions.reason, self.ready,
            None if sub is None else sub.topic_name, None if sub is None else sub.qos_profile,
            None if info is None else info.topic_name, self._camera_info is not None,
            {name: pub.get_subscription_count() for name, pub in self._pubs.items()},
            worker is not None and worker.mailbox.waiting, self._security.secured,
            None if self._stream is None else self._stream.mask)

    # ------------------------------------------------------------------------------------------ parameters
    def _declare_parameters(self) -> None:
        """Declare ``preset`` first; its values become the other parameters' defaults (params.declared_defaults)."""
        spec = self._specs["preset"]
        preset = self.declare_parameter("preset", spec.default, descriptor(spec)).value
        for name, value in declared_defaults(preset).items():
            self.declare_parameter(name, value, descriptor(self._specs[name]))

    def _values(self, changes: list[Parameter] | None = None) -> dict[str, Any]:
        """Current values of our parameters with ``changes`` laid over them."""
        values = {name: self.get_parameter(name).value for name in self._specs}
        for p in changes or []:
            if p.name in self._specs:
                values[p.name] = p.value
        return values

    def _expand_preset(self, params: list[Parameter]) -> list[Parameter]:
        """Pre-set callback: a preset brings its group, a model its calibrated weights, ``constraint`` mass the
        density photometric mode (params.expand_preset)."""
        given = [(p.name, p.value) for p in params]
        return params + [Parameter(k, value=v) for k, v in expand_preset(
            given, self.get_parameter("model").value, self.get_parameter("constraint").value)]

    def _validate(self, params: list[Parameter]) -> SetParametersResult:
        """On-set callback: the whole would-be configuration must be valid, else nothing changes."""
        try:
            settings_from_values(self._values(params))
            motion_from_values(self._values(params))
        except ConfigError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _apply(self, params: list[Parameter]) -> None:
        """Post-set callback: the stream picks the new settings up on the next frame (unconfigured: configure
        reads them)."""
        if any(p.name in self._specs for p in params):
            s = settings_from_values(self._values())
            if self._stream is not None and self._motion is not None:
                self._stream.update(s.config, s.input_scale, s.color_max_flow, s.flow_units)
                self._motion.update(motion_from_values(self._values()))
            self.get_logger().info("parameters changed: " + ", ".join(f"{p.name}={p.value!r}" for p in params))

    @property
    def settings(self) -> StreamSettings:
        """The settings in effect, or, unconfigured, those configure would apply (ConfigError if invalid)."""
        return self._stream.settings if self._stream is not None else settings_from_values(self._values())

    # ------------------------------------------------------------------------------------------ callbacks
    def _on_image(self, msg: Image | CompressedImage) -> None:
        """Subscription callback (active only): never blocks; the newest frame replaces a waiting one."""
        if not self._executor_checked:  # here the node is known to be spinning, and by which executor
            self._executor_checked = True
            if advice := executor_advice(self.executor):
                self.get_logger().warning(advice)
        if self._worker is not None:
            self._stats.received(self._worker.mailbox.put(msg))

    def _on_camera_info(self, msg: CameraInfo) -> None:
        self._camera_info = msg  # the latest; republished scaled with each flow (camera_info.py)

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        if self._stream is not None:
            self._stream.reset()
        response.success, response.message = True, "previous frame dropped; the next frame starts a new pair"
        return response

    def _publish_diagnostics(self) -> None:
        w = self._stats.window()
        hw = self.get_parameter("hardware_id").value or self._frame_id or "unknown"
        stream = self._stream
        model, scale = ((stream.settings.config.model, stream.settings.input_scale) if stream is not None else
                        (self.get_parameter("model").value, self.get_parameter("input_scale").value))
        st = diagnostics.status(w, name=f"{self.get_name()}: optical flow", hardware_id=hw, ready=self.ready,
                                backend="none" if stream is None else stream.backend, model=model,
                                input_scale=scale, resolution=self._resolution,
                                backend_warning=self._backend_warning, lifecycle_state=lifecycle.state_label(self),
                                failure=self._transitions.reason)
        if st.message.startswith("solver too slow"):
            self.get_logger().warning(st.message, throttle_duration_sec=10.0)
        sec = security.statuses(self._security, self.get_name(), hw)
        self._pub_diag.publish(diagnostics.array(self.get_clock().now().to_msg(), [st, *sec]))

    # ------------------------------------------------------------------------------------------ worker
    def _warmup(self) -> None:
        assert self._stream is not None  # the worker runs between configure and cleanup
        seconds = self._stream.warmup()
        seconds += warm_fits(fits_for(self._stream.backend))  # the derived outputs' fits (numba: compiled)
        self.get_logger().info(f"engine warm-up ({self._stream.backend}) took {seconds:.2f} s")

    def _frame_failed(self, exc: Exception) -> bool:
        """A frame raised: counted and logged; False (stop the worker) when the process is shutting down."""
        if not self.context.ok():
            return False  # SIGINT/SIGTERM: the publishers are gone, nothing to report
        self._stats.error(f"{type(exc).__name__}: {exc}")
        self.get_logger().error(f"frame failed: {type(exc).__name__}: {exc}", throttle_duration_sec=5.0)
        return True

    @property
    def ready(self) -> bool:
        """True once configured and the warm-up is done (frames are processed while active)."""
        return self._worker is not None and self._worker.ready

    def _handle(self, msg: Image | CompressedImage) -> None:
        stream, motion = self._stream, self._motion
        assert stream is not None and motion is not None  # the worker runs between configure and cleanup
        start = time.perf_counter()
        try:
            frame, label = decode(msg)
            self._frame_id = msg.header.frame_id
            out = stream.process(frame, stamp_ns(msg.header), label)  # in the settings' flow_units
        except InputError as exc:
            self._stats.rejected(str(exc))
            self.get_logger().warning(f"image rejected: {exc}", throttle_duration_sec=5.0)
            return
        if out is None:
            motion.reset()  # a new pair: "motion detected" starts again from off
            self._stats.reset(stream.last_reset_reason)
            self.get_logger().info(f"new pair started: {stream.last_reset_reason}")
            return
        self._resolution = f"{out.flow.shape[1]}x{out.flow.shape[0]}"
        with self._gate:  # deactivate waits for a publish in progress, then nothing more goes out
            if not self._active:
                self._stats.dropped()  # solved as the node was deactivated: not published
                return
            publish_s = publish_outputs(self._pubs, msg.header, out, self._camera_info, self.get_logger())
            motion_s = motion.publish(self._pubs, msg.header, out)  # only what ~/motion/* subscribers need
        if motion_s is not None:
            self._stats.analysed(motion_s)
        self._stats.solved(out.seconds, time.perf_counter() - start - out.seconds, publish_s, out)

    def destroy_node(self) -> None:
        """Stop the worker (after the frame it is solving) and destroy the node."""
        if self._worker is not None:
            self._worker.stop()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run flow_node flow_node`` / ``python -m flow_node.ros.node``. Spins the node on a
    SingleThreadedExecutor until Ctrl-C/SIGTERM or its shutdown transition; exit code 0, or 1 with a one-line
    reason when it cannot start (an unmanaged node whose configure failed: invalid parameters)."""
    keep_freed_memory()
    passive_thread_waits()
    defer_kernel_bitcode()
    middleware.use_shipped_dds_profile()  # ros2 run, ros2 launch and python -m get the same delivery
    argv = sys.argv if args is None else args
    log = rclpy.logging.get_logger("flow_node")
    try:
        startup.check_params_files(argv)
        rclpy.init(args=argv)
    except ConfigError as exc:
        log.fatal(f"cannot start: {exc}")
        return 1
    except RCLError as exc:  # what rcl refuses beyond the checks above (a bad remap, log level, ...)
        log.fatal(f"cannot start: {startup.rcl_error_line(exc)}")
        return 1
    node: FlowNode | None = None
    executor = SingleThreadedExecutor()  # not rclpy's MultiThreadedExecutor: docs/node.md, "Threading"
    code = 0
    try:
        node = FlowNode()
        executor.add_node(node)
        executor.spin_until_future_complete(node.finalized)  # Ctrl-C/SIGTERM end it too
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (FlowError, ParameterException) as exc:
        log.fatal(f"cannot start: {exc}")
        code = 1
    finally:
        executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return code


if __name__ == "__main__":
    raise SystemExit(main())
