"""The shipped SROS2 policy: it is the generator's default output, and its names are the node's own.

The last test starts the node (real rclpy over DDS, no security needed) renamed, in a namespace and with a
remapped input, and compares what rcl reports it created with what the generator writes for those options.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import rclpy
from rclpy.context import Context
from rclpy.parameter import Parameter
from ros_helpers import FAST

from flow_node.pipeline.derived import MOTION_TOPICS
from flow_node.ros import security_policy as sp
from flow_node.ros.names import camera_info_topic
from flow_node.ros.node import FlowNode

pytestmark = pytest.mark.ros  # rclpy over DDS: a node or a publisher in this process, or a node process

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "config" / "flow_node.policy.xml"


def rules(xml: str, profile_index: int = 0) -> dict[str, set[str]]:
    """{access: names} of a profile of an sros2 policy (e.g. {"publish": {"~/flow", ...}})."""
    root = ET.fromstring(xml)
    assert root.tag == "policy" and root.get("version") == "0.2.0"
    profile = root.findall("enclaves/enclave/profiles/profile")[profile_index]
    out: dict[str, set[str]] = {}
    for group in profile:
        ((access, verdict),) = group.attrib.items()
        assert verdict == "ALLOW"
        out.setdefault(access, set()).update(e.text or "" for e in group)
    return out


def test_shipped_policy_is_the_generators_default_output() -> None:
    assert SHIPPED.read_text() == sp.render([]), "regenerate: python -m flow_node.ros.security_policy > " + str(
        SHIPPED.relative_to(ROOT))
    assert "config/flow_node.policy.xml" in (ROOT / "setup.py").read_text()  # installed to share/flow_node


def test_default_policy_lists_the_node_interfaces() -> None:
    root = ET.fromstring(SHIPPED.read_text())
    (enclave,) = root.findall("enclaves/enclave")
    (profile,) = enclave.findall("profiles/profile")
    assert (enclave.get("path"), profile.get("ns"), profile.get("node")) == ("/flow_node", "/", "flow_node")
    got = rules(SHIPPED.read_text())
    assert got["subscribe"] == {"image", "camera_info", "~/mask"}
    assert got["publish"] == {"~/flow", "~/magnitude", "~/flow_color", "~/confidence", "~/flow_pair",
                              "~/camera_info", "/diagnostics", "/rosout", "/parameter_events", "~/transition_event"} | {
        f"~/{name}" for name in MOTION_TOPICS}  # the derived outputs ~/motion/*
    assert got["reply"] == {"~/reset", "~/get_type_description"} | {
        f"~/{s}" for s in ("describe_parameters", "get_parameter_types", "get_parameters", "list_parameters",
                           "set_parameters", "set_parameters_atomically")} | {  # the lifecycle services
        f"~/{s}" for s in ("change_state", "get_state", "get_available_states", "get_available_transitions",
                           "get_transition_graph")}
    assert "request" not in got  # the node calls no service


@pytest.mark.parametrize(("name", "ns", "node", "expected"), [
    ("/diagnostics", "/robot", "n", "/diagnostics"),
    ("~/flow", "/", "flow_node", "/flow_node/flow"),
    ("~/flow", "/robot/", "cam_flow", "/robot/cam_flow/flow"),
    ("image", "/", "flow_node", "/image"),
    ("image", "robot", "flow_node", "/robot/image"),
    ("cam/image", "/a/b", "x", "/a/b/cam/image"),
])
def test_resolve_follows_ros_name_rules(name: str, ns: str, node: str, expected: str) -> None:
    assert sp.resolve(name, ns, node) == expected


def test_options_adapt_the_profile_and_the_input() -> None:
    xml = sp.render(["--image", "/camera/image_raw", "--namespace", "/robot", "--name", "cam_flow"])
    root = ET.fromstring(xml)
    assert root.find("enclaves/enclave").get("path") == "/robot/cam_flow"
    profile = root.find("enclaves/enclave/profiles/profile")
    assert (profile.get("ns"), profile.get("node")) == ("/robot", "cam_flow")
    assert rules(xml)["subscribe"] == {"/camera/image_raw", "/camera/camera_info", "~/mask"}
    assert rules(sp.render(["--compressed", "--enclave", "/e"]))["subscribe"] == {"image/compressed", "camera_info",
                                                                                  "~/mask"}
    assert rules(sp.render(["--sim-time"]))["subscribe"] == {"image", "camera_info", "/clock", "~/mask"}
    assert "with image=/camera/image_raw, namespace=/robot, name=cam_flow" in xml  # the header says how


def test_client_policy_mirrors_the_node() -> None:
    xml = sp.render(["--client", "--namespace", "/robot", "--image", "/cam/image"])
    nodes = [p.get("node") for p in ET.fromstring(xml).findall("enclaves/enclave/profiles/profile")]
    assert nodes == ["flow_client", "_ros2cli_*"]  # a client node and the ros2 CLI's (ros2 param set ...)
    assert rules(xml, 0) == rules(xml, 1)
    got = rules(xml)
    assert {"/cam/image", "/cam/camera_info"} <= got["publish"] and {"/rosout", "/parameter_events"} <= got["publish"]
    assert got["subscribe"] == {"/robot/flow_node/flow", "/robot/flow_node/magnitude", "/robot/flow_node/flow_color",
                                "/robot/flow_node/confidence", "/robot/flow_node/flow_pair",
                                "/robot/flow_node/camera_info", "/diagnostics", "/robot/flow_node/transition_event"} | {
        f"/robot/flow_node/{name}" for name in MOTION_TOPICS}
    assert "/robot/flow_node/reset" in got["request"] and "/robot/flow_node/set_parameters" in got["request"]
    assert "/robot/flow_node/change_state" in got["request"]  # a client may manage the node
    assert got["reply"] == {n for n in sp.NODE_BASICS if n.startswith("~")}  # the client node's own services


@pytest.mark.parametrize("compressed", [False, True])
def test_policy_names_are_what_the_node_creates(compressed: bool) -> None:
    """Renamed, namespaced and remapped: rcl's graph of the node equals the generated policy, resolved."""
    ns, name, image = f"/sec_policy_ns{int(compressed)}", "cam_flow", "/sec_policy_cam/image_raw"
    params = {**FAST, "warmup": False, "use_compressed": compressed}
    ctx = Context()
    rclpy.init(context=ctx)
    try:
        node = FlowNode(name, namespace=ns, context=ctx, cli_args=["--ros-args", "-r", f"image:={image}"],
                        parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
        try:
            created = {
                "publish": {t for t, _ in node.get_publisher_names_and_types_by_node(name, ns)},
                "subscribe": {t for t, _ in node.get_subscriber_names_and_types_by_node(name, ns)},
                "reply": {s for s, _ in node.get_service_names_and_types_by_node(name, ns)},
            }
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)
    policy = rules(sp.render(["--image", image, "--namespace", ns, "--name", name]
                             + (["--compressed"] if compressed else [])))
    resolved = {a: {sp.resolve(n, ns, name) for n in names} for a, names in policy.items()}
    for access in ("publish", "subscribe", "reply"):
        missing, extra = created[access] - resolved[access], resolved[access] - created[access]
        assert not missing, f"{access}: the policy misses {missing} (add a row to INTERFACES)"
        assert not extra, f"{access}: the policy allows {extra}, which the node does not create"
    assert f"{ns}/{name}/reset" in created["reply"]
    assert created["subscribe"] == {image + ("/compressed" if compressed else ""), camera_info_topic(image),
                                    f"{ns}/{name}/mask"}
