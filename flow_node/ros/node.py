"""The flow_node ROS 2 node: wires topics, parameters, a service and diagnostics to the pipeline.

Threading: the subscription callback (executor) only drops the message into a one-slot mailbox (latest
wins; a replaced message is counted as dropped) and returns. A dedicated worker thread takes the newest
message, decodes it, runs :class:`~flow_node.pipeline.stream.FlowStream` and publishes. The executor thus
never runs a solve, so parameter services, ``~/reset`` and diagnostics answer while a frame is being
solved, and memory is bounded by two images (the one solving and the one waiting).
"""

from __future__ import annotations

import array
import sys
import threading
import time
from typing import Any

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy._rclpy_pybind11 import RCLError
from rclpy.exceptions import ParameterException
from rclpy.executors import Executor, ExternalShutdownException, MultiThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, qos_profile_sensor_data
from rclpy.qos_overriding_options import QoSOverridingOptions
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, TimeReference
from std_msgs.msg import Header
from std_srvs.srv import Trigger

from ..core.backends import fallback_warning
from ..core.config import implied_weights
from ..core.errors import ConfigError, FlowError, InputError
from ..pipeline.codec import array_to_image_fields, decode
from ..pipeline.stream import FlowOutput, FlowStream, StreamSettings
from ..pipeline.units import output_in_units
from ..process import keep_freed_memory, passive_thread_waits
from . import camera_info, diagnostics, security, startup
from .params import ParamSpec, coerce, param_specs, preset_values, settings_from_values

_TYPES = {bool: Parameter.Type.BOOL, int: Parameter.Type.INTEGER, float: Parameter.Type.DOUBLE,
          str: Parameter.Type.STRING}


def descriptor(spec: ParamSpec) -> ParameterDescriptor:
    """ROS descriptor of a parameter: type, description, choices, Integer/FloatingPointRange, read_only."""
    d = ParameterDescriptor(name=spec.name, type=_TYPES[spec.type].value, description=spec.description,
                            read_only=spec.read_only)
    if spec.choices is not None:
        d.additional_constraints = "one of: " + ", ".join(repr(c) for c in spec.choices)
    if spec.lo is not None and spec.hi is not None:
        if spec.type is float:
            d.floating_point_range = [FloatingPointRange(from_value=float(spec.lo), to_value=float(spec.hi),
                                                         step=0.0)]
        elif spec.type is int and spec.choices is None:
            d.integer_range = [IntegerRange(from_value=int(spec.lo), to_value=int(spec.hi), step=1)]
    return d


# The generated Image class keeps ``data`` in this slot; its setter turns anything but an array.array into one
# (a full copy), while the C conversion in ``publish`` takes any buffer (rosidl's fast path for arrays of
# primitives) and copies it once into the C message.
_DIRECT_DATA = "_data" in getattr(Image, "__slots__", ())


def image_msg(header: Header, fields: dict[str, Any]) -> Image:
    """An rclpy Image from a header and :func:`array_to_image_fields` output, for publishing.

    The numpy payload goes into the message without a Python-side copy (``_DIRECT_DATA``; at 640x480 32FC2
    the copy into an ``array.array`` cost ~0.5 ms a frame); ``publish`` copies it once into the C message.
    Such a message's ``data`` is then the numpy array, so it is for publishing, not for handing around.
    """
    msg = Image(header=header, height=fields["height"], width=fields["width"], encoding=fields["encoding"],
                is_bigendian=fields["is_bigendian"], step=fields["step"])
    payload = fields["data"]  # contiguous 1-D uint8 (array_to_image_fields)
    if _DIRECT_DATA:
        msg._data = payload  # noqa: SLF001 -- see _DIRECT_DATA
    else:
        data = array.array("B")
        data.frombytes(payload)
        msg.data = data
    return msg


def executor_advice(executor: Executor | None) -> str | None:
    """A warning if ``executor`` is one the node is known to run badly on, else None.

    rclpy's MultiThreadedExecutor (Jazzy's 7.1.6 at least; ros2/rclpy#1452) re-queues callbacks that have
    not started yet and keeps its spin thread polling while they wait, so under a high input rate it holds
    the GIL: the node takes a fraction of the frames and solves many times slower (bench.node_flood,
    BENCHMARKS.md).
    """
    if isinstance(executor, MultiThreadedExecutor):
        return ("spun by rclpy's MultiThreadedExecutor, which can starve the solver at high input rates "
                "(ros2/rclpy#1452; docs/node.md): spin this node with a SingleThreadedExecutor (rclpy.spin)")
    return None


def stamp_ns(header: Header) -> int:
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


class Mailbox:
    """A one-slot queue: ``put`` replaces what is waiting (returns True if it did), ``take`` blocks."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._item: Any = None
        self._closed = False

    def put(self, item: Any) -> bool:
        with self._cond:
            replaced = self._item is not None
            self._item = item
            self._cond.notify()
            return replaced

    def take(self) -> Any:
        """The waiting item, or None once closed."""
        with self._cond:
            while self._item is None and not self._closed:
                self._cond.wait()
            item, self._item = self._item, None
            return None if self._closed else item

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()


class FlowNode(Node):
    """Optical flow between consecutive frames of ``image``; see docs/node.md for the interface."""

    def __init__(self, node_name: str = "flow_node", **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self._specs = {s.name: s for s in param_specs()}
        self._declare_parameters()
        settings = settings_from_values(self._values())  # raises ConfigError for a bad params file
        self._stream = FlowStream(settings)
        self._stats = diagnostics.NodeStats()
        self._mailbox = Mailbox()
        self._ready = threading.Event()
        self._resolution = "none yet"
        self._frame_id = ""
        self._executor_checked = False
        self._units: str = self.get_parameter("flow_units").value
        self._camera_info: CameraInfo | None = None
        self._backend_warning = fallback_warning(settings.config.backend, self._stream.backend)

        overrides = QoSOverridingOptions.with_default_policies()
        self._pub_flow = self.create_publisher(Image, "~/flow", 1, qos_overriding_options=overrides)
        self._pub_mag = self.create_publisher(Image, "~/magnitude", 1, qos_overriding_options=overrides)
        self._pub_color = self.create_publisher(Image, "~/flow_color", 1, qos_overriding_options=overrides)
        self._pub_pair = self.create_publisher(TimeReference, "~/flow_pair", 1, qos_overriding_options=overrides)
        self._pub_info = self.create_publisher(CameraInfo, "~/camera_info", 1, qos_overriding_options=overrides)
        self._pub_conf = self.create_publisher(Image, "~/confidence", 1, qos_overriding_options=overrides)
        self._pub_diag = self.create_publisher(diagnostics.DiagnosticArray, "/diagnostics", 10)
        qos = QoSProfile(**{k: getattr(qos_profile_sensor_data, k) for k in ("reliability", "durability",
                                                                           "history")}, depth=1)
        if self.get_parameter("use_compressed").value:
            topic = self.resolve_topic_name("image") + "/compressed"
            self._sub = self.create_subscription(CompressedImage, topic, self._on_image, qos,
                                                 qos_overriding_options=overrides)
        else:
            self._sub = self.create_subscription(Image, "image", self._on_image, qos,
                                                 qos_overriding_options=overrides)
        self._sub_info = self.create_subscription(
            CameraInfo, camera_info.camera_info_topic(self.resolve_topic_name("image")), self._on_camera_info, qos)
        self._srv_reset = self.create_service(Trigger, "~/reset", self._on_reset)
        self.add_pre_set_parameters_callback(self._expand_preset)
        self.add_on_set_parameters_callback(self._validate)
        self.add_post_set_parameters_callback(self._apply)
        self._diag_timer = self.create_timer(self.get_parameter("diagnostics_period").value, self._publish_diagnostics)
        self.get_logger().info(f"subscribed to {self._sub.topic_name}; model {settings.config.model}, "
                               f"backend {self._stream.backend}; {startup.middleware_line()}")
        if self._backend_warning:
            self.get_logger().warning(self._backend_warning)
        self._security = security.check_and_log(self)  # warns when SROS2 is asked for but not in effect
        # last: the worker logs the warm-up, which tools and tests take as "started", so everything above
        # (the security verdict included) is in the log before it
        self._worker = threading.Thread(target=self._run, name=f"{node_name}_worker", daemon=True)
        self._worker.start()

    # ------------------------------------------------------------------------------------------ parameters
    def _declare_parameters(self) -> None:
        """Declare ``preset`` first; its values (if any) become the defaults of the other parameters, so a
        params file with ``preset: realtime`` and ``iterations: 20`` means realtime with 20 iterations."""
        spec = self._specs["preset"]
        preset = self.declare_parameter("preset", spec.default, descriptor(spec)).value
        try:
            base = preset_values(preset) if preset else {}
        except ConfigError as exc:
            raise ConfigError(f"parameter {exc}") from None
        for name, spec in self._specs.items():
            if name != "preset":
                self.declare_parameter(name, base.get(name, spec.default), descriptor(spec))

    def _values(self, changes: list[Parameter] | None = None) -> dict[str, Any]:
        """Current values of our parameters with ``changes`` laid over them."""
        values = {name: self.get_parameter(name).value for name in self._specs}
        for p in changes or []:
            if p.name in self._specs:
                values[p.name] = p.value
        return values

    def _expand_preset(self, params: list[Parameter]) -> list[Parameter]:
        """Pre-set callback: setting ``preset`` also sets its group, setting ``model`` its calibrated weights
        (config.implied_weights); values given in the same call win."""
        names = {p.name for p in params}
        out = list(params)
        for p in params:
            if p.name == "preset" and p.value and isinstance(p.value, str):
                try:
                    group = preset_values(p.value)
                except ConfigError:
                    continue  # _validate rejects it with the reason
                out += [Parameter(k, value=coerce(self._specs[k], v)) for k, v in group.items() if k not in names]
        given = {p.name: p.value for p in out}  # a new model without weights brings its calibrated ones
        out += [Parameter(k, value=v) for k, v in implied_weights(self.get_parameter("model").value, given).items()]
        return out

    def _validate(self, params: list[Parameter]) -> SetParametersResult:
        """On-set callback: the whole would-be configuration must be valid, else nothing changes."""
        try:
            settings_from_values(self._values(params))
        except ConfigError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _apply(self, params: list[Parameter]) -> None:
        """Post-set callback: the stream picks the new settings up on the next frame."""
        if any(p.name in self._specs for p in params):
            s = settings_from_values(self._values())
            self._stream.update(s.config, s.input_scale, s.color_max_flow)
            self._units = self.get_parameter("flow_units").value
            self.get_logger().info("parameters changed: " + ", ".join(f"{p.name}={p.value!r}" for p in params))

    @property
    def settings(self) -> StreamSettings:
        return self._stream.settings

    # ------------------------------------------------------------------------------------------ callbacks
    def _on_image(self, msg: Image | CompressedImage) -> None:
        """Subscription callback: never blocks; the newest frame replaces a waiting one."""
        if not self._executor_checked:  # here the node is known to be spinning, and by which executor
            self._executor_checked = True
            if advice := executor_advice(self.executor):
                self.get_logger().warning(advice)
        self._stats.received(self._mailbox.put(msg))

    def _on_camera_info(self, msg: CameraInfo) -> None:
        self._camera_info = msg  # the latest; republished scaled with each flow (camera_info.py)

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        self._stream.reset()
        response.success, response.message = True, "previous frame dropped; the next frame starts a new pair"
        return response

    def _publish_diagnostics(self) -> None:
        w = self._stats.window()
        hw = self.get_parameter("hardware_id").value or self._frame_id or "unknown"
        s = self._stream.settings
        st = diagnostics.status(w, name=f"{self.get_name()}: optical flow", hardware_id=hw,
                                ready=self._ready.is_set(), backend=self._stream.backend, model=s.config.model,
                                input_scale=s.input_scale, resolution=self._resolution,
                                backend_warning=self._backend_warning)
        if st.message.startswith("solver too slow"):
            self.get_logger().warning(st.message, throttle_duration_sec=10.0)
        sec = security.statuses(self._security, self.get_name(), hw)
        self._pub_diag.publish(diagnostics.array(self.get_clock().now().to_msg(), [st, *sec]))

    # ------------------------------------------------------------------------------------------ worker
    def _run(self) -> None:
        if self.get_parameter("warmup").value:
            seconds = self._stream.warmup()
            self.get_logger().info(f"engine warm-up ({self._stream.backend}) took {seconds:.2f} s")
        self._ready.set()
        while (msg := self._mailbox.take()) is not None:
            try:
                self._handle(msg)
            except Exception as exc:  # the node never dies on a frame; report and go on
                if not self.context.ok():
                    break  # shutting down (SIGINT/SIGTERM): the publishers are gone, nothing to report
                self._stats.error(f"{type(exc).__name__}: {exc}")
                self.get_logger().error(f"frame failed: {type(exc).__name__}: {exc}", throttle_duration_sec=5.0)

    @property
    def ready(self) -> bool:
        """True once the warm-up is done and frames are being processed."""
        return self._ready.is_set()

    def _handle(self, msg: Image | CompressedImage) -> None:
        start = time.perf_counter()
        try:
            frame, label = decode(msg)
            self._frame_id = msg.header.frame_id
            out = self._stream.process(frame, stamp_ns(msg.header), label)
            if out is not None:
                out = output_in_units(out, self._units)
        except InputError as exc:
            self._stats.rejected(str(exc))
            self.get_logger().warning(f"image rejected: {exc}", throttle_duration_sec=5.0)
            return
        if out is None:
            self._stats.reset(self._stream.last_reset_reason)
            self.get_logger().info(f"new pair started: {self._stream.last_reset_reason}")
            return
        self._resolution = f"{out.flow.shape[1]}x{out.flow.shape[0]}"
        publish_s = self._publish(msg.header, out)
        self._stats.solved(out.seconds, time.perf_counter() - start - out.seconds, publish_s, out)

    def _publish(self, header: Header, out: FlowOutput) -> float:
        """Flow, magnitude, colour and confidence with the new frame's header; each is built and published only
        while its topic has subscribers (colour and confidence are not even computed otherwise). Returns the seconds
        spent inside rclpy's ``publish`` (C conversion, serialisation and the middleware's send)."""
        publish_s = 0.0
        for pub, image, encoding in ((self._pub_flow, lambda: out.flow, "32FC2"),
                                     (self._pub_mag, lambda: out.magnitude, "32FC1"),
                                     (self._pub_color, out.color, "bgr8"),
                                     (self._pub_conf, out.confidence, "32FC1")):
            if pub.get_subscription_count() > 0:
                msg = image_msg(header, array_to_image_fields(image(), encoding))
                t0 = time.perf_counter()
                pub.publish(msg)
                publish_s += time.perf_counter() - t0
        self._publish_companions(header, out)
        return publish_s

    def _publish_companions(self, header: Header, out: FlowOutput) -> None:
        """~/flow_pair (the pair's earlier stamp) and ~/camera_info (the input's, scaled to the output grid),
        both with the flow's header, while subscribed."""
        if self._pub_pair.get_subscription_count() > 0:
            earlier = divmod(out.previous_stamp_ns, 1_000_000_000)
            pair = TimeReference(header=header, source="earlier_frame")
            pair.time_ref.sec, pair.time_ref.nanosec = earlier
            self._pub_pair.publish(pair)
        info = self._camera_info
        if info is not None and self._pub_info.get_subscription_count() > 0:
            if reason := camera_info.unscalable(info):
                self.get_logger().warning(f"{reason}: ~/camera_info not published", throttle_duration_sec=30.0)
                return
            h, w = out.flow.shape[:2]
            self._pub_info.publish(camera_info.scaled_camera_info(info, w, h, header))

    def destroy_node(self) -> None:
        """Stop the worker (after the frame it is solving) and destroy the node."""
        self._mailbox.close()
        if self._worker.is_alive() and threading.current_thread() is not self._worker:
            self._worker.join(timeout=30.0)
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run flow_node flow_node`` / ``python -m flow_node.ros.node``."""
    keep_freed_memory()
    passive_thread_waits()
    startup.use_shipped_dds_profile()  # ros2 run, ros2 launch and python -m get the same delivery
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
    code = 0
    try:
        node = FlowNode()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (FlowError, ParameterException) as exc:
        log.fatal(f"cannot start: {exc}")
        code = 1
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return code


if __name__ == "__main__":
    raise SystemExit(main())
