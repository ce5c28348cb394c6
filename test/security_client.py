"""Clients for test_security_route.py, run by it in the security route's environment (a DDS with DDS-Security):

    python test/security_client.py feed SECONDS [--ros-args --enclave E]   feed the node and report (JSON)
    python test/security_client.py start ENCLAVE...                        try starting FlowNode per enclave

``feed``: a node named flow_client listens to /diagnostics for 2.5 s, then publishes the exact test pair
(I0, I1, I0, ... every 0.2 s; I1 frames have odd stamps) on /image, collects /flow_node/flow and
/diagnostics, then, if it saw flow, calls ~/reset and sets ``alpha`` through the parameter service. Whatever
the middleware refuses is reported, not raised. ``start``: for each enclave, a context with that enclave and a
FlowNode in it; reports the error, if any (the test runs one enclave per process).
The last line of stdout is the JSON report.
"""

from __future__ import annotations

import json
import sys
import time
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from ros_helpers import I0, I1, image, mono8
from sensor_msgs.msg import Image
from small_frames import PARAMS
from std_srvs.srv import Trigger

from flow_node.pipeline.codec import image_to_array

NODE = "/flow_node"


def call(node: Node, executor: SingleThreadedExecutor, srv_type: Any, name: str, request: Any) -> Any:
    """The response of service ``name``, or the reason there is none, as a string."""
    try:
        cli = node.create_client(srv_type, name)
    except Exception as exc:  # refused by access control
        return f"client refused: {exc}"
    if not cli.wait_for_service(timeout_sec=5.0):
        return "service not available"
    future = cli.call_async(request)
    executor.spin_until_future_complete(future, timeout_sec=5.0)
    return future.result() if future.done() else "no response"


def feed(seconds: float, args: list[str]) -> dict[str, Any]:
    ctx = Context()
    rclpy.init(args=args, context=ctx)
    node = Node("flow_client", context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    report: dict[str, Any] = {"flows": 0, "flow_means": [], "diagnostics": {}, "publisher_error": None}
    flows: list[Image] = []
    node.create_subscription(Image, f"{NODE}/flow", flows.append, 10)

    def on_diag(msg: DiagnosticArray) -> None:
        for st in msg.status:
            level = st.level[0] if isinstance(st.level, bytes) else int(st.level)
            report["diagnostics"][st.name] = {"level": level, "message": st.message,
                                              "values": {kv.key: kv.value for kv in st.values}}

    node.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 10)
    try:
        pub = node.create_publisher(Image, "/image", 10)
    except Exception as exc:  # refused by access control
        pub, report["publisher_error"] = None, str(exc)
    i0, i1 = mono8(I0), mono8(I1)
    end = time.monotonic() + 2.5  # first listen: the node's count of received frames before this client fed it
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=0.1)
    health = report["diagnostics"].get("flow_node: optical flow")
    report["received_before"] = health and health["values"]["frames received"]
    end, k = time.monotonic() + seconds, 0
    while time.monotonic() < end:
        if pub is not None:
            pub.publish(image(i1 if k % 2 else i0, "mono8", (100 + k) * 1_000_000_000))
            k += 1
        executor.spin_once(timeout_sec=0.2)
    executor.spin_once(timeout_sec=1.0)
    report["node_visible"] = NODE in {f"{ns.rstrip('/')}/{n}" for n, ns in node.get_node_names_and_namespaces()}
    report["image_subscribers"] = pub.get_subscription_count() if pub is not None else None
    report["flows"] = len(flows)
    report["flow_means"] = [[float(x) for x in image_to_array(m).reshape(-1, 2).mean(axis=0)]
                            for m in flows if m.header.stamp.sec % 2]  # the I0 -> I1 pairs
    if flows:
        reset = call(node, executor, Trigger, f"{NODE}/reset", Trigger.Request())
        report["reset"] = reset if isinstance(reset, str) else [reset.success, reset.message]
        req = SetParameters.Request(parameters=[Parameter("alpha", value=0.75).to_parameter_msg()])
        res = call(node, executor, SetParameters, f"{NODE}/set_parameters", req)
        report["set_alpha"] = res if isinstance(res, str) else [r.successful for r in res.results]
        got = call(node, executor, GetParameters, f"{NODE}/get_parameters", GetParameters.Request(names=["alpha"]))
        report["alpha"] = got if isinstance(got, str) else got.values[0].double_value
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown(context=ctx)
    return report


def start(enclaves: list[str]) -> dict[str, Any]:
    from flow_node.ros.node import FlowNode

    report: dict[str, Any] = {}
    for enclave in enclaves:
        ctx = Context()
        try:
            rclpy.init(args=["--ros-args", "--enclave", enclave], context=ctx)
            node = FlowNode("flow_node", context=ctx, parameter_overrides=[
                Parameter(k, value=v) for k, v in {**PARAMS, "warmup": False}.items()])
            node.destroy_node()
            report[enclave] = None
        except Exception as exc:
            report[enclave] = f"{type(exc).__name__}: {exc}"
        finally:
            rclpy.try_shutdown(context=ctx)
    return report


def main(argv: list[str]) -> int:
    role = argv[0]
    report = feed(float(argv[1]), argv[2:]) if role == "feed" else start(argv[1:])
    print(json.dumps(report, default=str))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
