"""The node's SROS2 access-control policy: one table of its interfaces, rendered as an sros2 policy XML.

``config/flow_node.policy.xml`` (installed to ``share/flow_node/config``) is :func:`main`'s output with no
arguments (a test checks it), i.e. for the node's default names. For a remapped image topic, a namespace or a
renamed node, generate the matching file and make the enclave's permissions from it (docs/security.md)::

    python -m flow_node.ros.security_policy --image /camera/image_raw --namespace /robot --name flow_node \\
        > policy.xml        # also: ros2 run flow_node flow_node_policy ...
    ros2 security create_permission KEYSTORE /robot/flow_node policy.xml

``--client`` writes the mirror image instead: a policy for a client enclave allowed to feed the node, read
every output and call every service (the tests' authorised client; a start for a camera driver or a viewer).

A new topic or service of the node is one row in :data:`INTERFACES`. The module is plain Python (no rclpy),
so the generator runs where ROS is not sourced.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from xml.sax.saxutils import escape

from .names import camera_info_topic

POLICY_VERSION = "0.2.0"  # the sros2 policy format (sros2/policy/schemas/policy.xsd)
IMAGE = "{image}"  # placeholder for the (remapped) input topic in INTERFACES
CAMERA_INFO = "{camera_info}"  # placeholder for the CameraInfo topic beside it (names.camera_info_topic)
DEFAULT_IMAGE = "image"  # the node subscribes the relative name ``image`` (resolved in its namespace)

# The access a participant needs, per kind of interface: topics are published or subscribed, services are
# replied (server) or requested (client). MIRROR gives the other side's access.
MIRROR = {"publish": "subscribe", "subscribe": "publish", "reply": "request", "request": "reply"}
KIND_OF = {"publish": "topics", "subscribe": "topics", "reply": "services", "request": "services"}


@dataclass(frozen=True)
class Interface:
    """One topic or service of the node: name as the node uses it (``~/`` = private, relative = in its
    namespace, ``/`` = absolute; :data:`IMAGE` = the input topic), the node's access, what it is for, and the
    generator option it exists under (``""`` = always)."""

    name: str
    access: str
    why: str
    when: str = ""


def _param_service(name: str, what: str) -> Interface:
    return Interface(f"~/{name}", "reply", f"parameter service (rcl_interfaces/srv/{what}): ros2 param, rqt")


def _lifecycle_service(name: str, what: str) -> Interface:
    return Interface(f"~/{name}", "reply", f"lifecycle service (lifecycle_msgs/srv/{what}): ros2 lifecycle, launch")


# Everything the node creates with its default settings, found by trial under Enforce (a missing entry stops
# the node at start-up, e.g. /rosout, or makes that interface fail). One row per interface.
INTERFACES: tuple[Interface, ...] = (
    Interface(IMAGE, "subscribe", "the camera images the flow is computed from (sensor_msgs/Image)", "raw"),
    Interface(IMAGE + "/compressed", "subscribe", "the compressed camera images (use_compressed: true)",
              "compressed"),
    Interface("~/flow", "publish", "the flow, sensor_msgs/Image 32FC2 (u, v) px/frame"),
    Interface("~/magnitude", "publish", "the flow length, sensor_msgs/Image 32FC1 px/frame"),
    Interface("~/flow_color", "publish", "the Middlebury colour coding, sensor_msgs/Image bgr8"),
    Interface("~/confidence", "publish", "the per-pixel confidence of the flow, sensor_msgs/Image 32FC1"),
    Interface("~/flow_pair", "publish", "each flow's pair: the earlier frame's stamp (sensor_msgs/TimeReference)"),
    Interface("~/camera_info", "publish", "the camera's CameraInfo scaled to the flow's grid"),
    Interface("~/motion/dominant", "publish", "the dominant image motion, geometry_msgs/TwistStamped per second"),
    Interface("~/motion/homography", "publish", "the dominant homography, std_msgs/Float64MultiArray 3x3"),
    Interface("~/motion/divergence", "publish", "the flow's divergence, sensor_msgs/Image 32FC1 1/frame"),
    Interface("~/motion/ttc", "publish", "time to contact per region, std_msgs/Float32MultiArray seconds"),
    Interface("~/motion/foe", "publish", "the focus of expansion, geometry_msgs/PointStamped px"),
    Interface("~/motion/moving_mask", "publish", "independently moving pixels, sensor_msgs/Image mono8"),
    Interface("~/motion/detected", "publish", "motion detected with hysteresis, std_msgs/Bool"),
    Interface(CAMERA_INFO, "subscribe", "the camera's CameraInfo beside the image topic (sensor_msgs/CameraInfo)"),
    Interface("~/mask", "subscribe", "the validity mask, sensor_msgs/Image mono8, nonzero = valid (optional)"),
    Interface("/diagnostics", "publish", "the node's health, diagnostic_msgs/DiagnosticArray"),
    Interface("/rosout", "publish", "the node's log (rcl_interfaces/msg/Log); without it the node cannot start"),
    Interface("/parameter_events", "publish", "parameter changes (rcl_interfaces/msg/ParameterEvent)"),
    Interface("/clock", "subscribe", "simulated time (use_sim_time: true)", "sim_time"),
    Interface("~/reset", "reply", "drop the previous frame (std_srvs/srv/Trigger)"),
    _param_service("describe_parameters", "DescribeParameters"),
    _param_service("get_parameter_types", "GetParameterTypes"),
    _param_service("get_parameters", "GetParameters"),
    _param_service("list_parameters", "ListParameters"),
    _param_service("set_parameters", "SetParameters"),
    _param_service("set_parameters_atomically", "SetParametersAtomically"),
    Interface("~/get_type_description", "reply",
              "the message type descriptions of the node's topics (type_description_interfaces, ROS 2 Jazzy)"),
    Interface("~/transition_event", "publish",
              "lifecycle state changes (lifecycle_msgs/msg/TransitionEvent): launch, lifecycle managers"),
    _lifecycle_service("change_state", "ChangeState"),
    _lifecycle_service("get_state", "GetState"),
    _lifecycle_service("get_available_states", "GetAvailableStates"),
    _lifecycle_service("get_available_transitions", "GetAvailableTransitions"),
    _lifecycle_service("get_transition_graph", "GetAvailableTransitions"),
)

# What any rclpy node (e.g. a client's own) creates by itself: the rows of INTERFACES that are not flow_node's.
NODE_BASICS = ("/rosout", "/parameter_events", "~/describe_parameters", "~/get_parameter_types",
               "~/get_parameters", "~/list_parameters", "~/set_parameters", "~/set_parameters_atomically",
               "~/get_type_description")


# The client policy's node names: a client node of that name, and the nodes the ros2 CLI creates for
# `ros2 param`, `ros2 service call`, `ros2 topic echo` (_ros2cli_<pid>; a DDS wildcard).
CLIENT_NODES = ("flow_client", "_ros2cli_*")


def namespace_of(namespace: str) -> str:
    """``robot``, ``/robot/`` -> ``/robot``; empty -> ``/``."""
    parts = [p for p in namespace.split("/") if p]
    return "/" + "/".join(parts)


def resolve(name: str, namespace: str, node: str) -> str:
    """A ROS name as rcl resolves it for node ``node`` in ``namespace``: ``/a`` stays, ``~/a`` ->
    ``<ns>/<node>/a``, ``a`` -> ``<ns>/a`` (the same rules as sros2's permission template)."""
    ns = namespace_of(namespace).rstrip("/")
    if name.startswith("/"):
        return name
    if name.startswith("~"):
        return f"{ns}/{node}{name[1:]}"
    return f"{ns}/{name}"


def node_interfaces(image: str = DEFAULT_IMAGE, *, compressed: bool = False,
                    sim_time: bool = False) -> list[Interface]:
    """The rows of :data:`INTERFACES` that apply, with :data:`IMAGE` replaced by ``image`` (as given to
    ``-r image:=...``: absolute, or relative to the node's namespace)."""
    on = {"", "compressed" if compressed else "raw"} | ({"sim_time"} if sim_time else set())
    info = camera_info_topic(image)
    return [replace(i, name=i.name.replace(IMAGE, image).replace(CAMERA_INFO, info)) for i in INTERFACES
            if i.when in on]


def client_interfaces(interfaces: Iterable[Interface], namespace: str, node: str) -> list[Interface]:
    """The other side of ``interfaces`` (of node ``node`` in ``namespace``), with absolute names, plus what
    the client's own rclpy node needs (:data:`NODE_BASICS`). The node's /rosout and /parameter_events are
    not mirrored: a client of the node has no need to read them."""
    basics = {i.name: i for i in INTERFACES if i.name in NODE_BASICS}
    mirrored = [Interface(resolve(i.name, namespace, node), MIRROR[i.access], f"flow_node: {i.why}")
                for i in interfaces if i.name not in basics or i.name.startswith("~")]
    return [basics[n] for n in NODE_BASICS] + mirrored


@dataclass(frozen=True)
class Profile:
    """The rules of one node (name, may be a DDS wildcard such as ``_ros2cli_*``) of an enclave."""

    namespace: str
    node: str
    interfaces: Sequence[Interface]


def policy_xml(enclave: str, profiles: Sequence[Profile], command: str) -> str:
    """An sros2 policy (format 0.2.0) with one enclave and its ``profiles``: an ALLOW list per access, the
    rows in table order, each with its purpose as a comment. ``command`` says how it was generated (header
    comment; without ``--``, which XML forbids in comments)."""
    if "--" in command:
        raise ValueError(f"'--' cannot appear in an XML comment: {command!r}")
    lines = ['<?xml version="1.0" encoding="UTF-8"?>',
             f"<!-- SROS2 access-control policy for flow_node. Generated by: {escape(command)}",
             "     (docs/security.md); regenerate it rather than editing it. -->",
             f'<policy version="{POLICY_VERSION}">', "  <enclaves>", f'    <enclave path="{escape(enclave)}">',
             "      <profiles>"]
    for p in profiles:
        lines.append(f'        <profile ns="{escape(namespace_of(p.namespace))}" node="{escape(p.node)}">')
        for access in ("subscribe", "publish", "reply", "request"):
            rows = [i for i in p.interfaces if i.access == access]
            if not rows:
                continue
            kind, item = KIND_OF[access], KIND_OF[access][:-1]
            lines.append(f'          <{kind} {access}="ALLOW">')
            lines += [f"            <{item}>{escape(i.name)}</{item}>  <!-- {escape(i.why)} -->" for i in rows]
            lines.append(f"          </{kind}>")
        lines.append("        </profile>")
    lines += ["      </profiles>", "    </enclave>", "  </enclaves>", "</policy>", ""]
    return "\n".join(lines)


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="flow_node_policy", description=__doc__.split("\n")[0])
    p.add_argument("--image", default=DEFAULT_IMAGE,
                   help="the input topic as remapped (-r image:=TOPIC); default: image (in the node's namespace)")
    p.add_argument("--namespace", default="/", help="the node's namespace (default /)")
    p.add_argument("--name", default="flow_node", help="the node's name (default flow_node)")
    p.add_argument("--enclave", default=None,
                   help="enclave path (default: the node's full name, /flow_node for the defaults)")
    p.add_argument("--compressed", action="store_true", help="the node runs with use_compressed: true")
    p.add_argument("--sim-time", action="store_true", help="the node runs with use_sim_time: true")
    p.add_argument("--client", action="store_true",
                   help="write the policy of a client enclave (default /flow_client) that may use every interface")
    p.add_argument("--client-nodes", default=",".join(CLIENT_NODES),
                   help="with --client: the client's node names, comma-separated, DDS wildcards allowed "
                        f"(default {','.join(CLIENT_NODES)}: a node named flow_client and the ros2 CLI's own)")
    return p


def render(argv: Sequence[str] = ()) -> str:
    """The policy XML for the generator arguments ``argv`` (see :func:`parser`)."""
    a = parser().parse_args(list(argv))
    interfaces = node_interfaces(a.image, compressed=a.compressed, sim_time=a.sim_time)
    defaults = vars(parser().parse_args([]))
    changed = [k if v is True else f"{k}={v}" for k, v in vars(a).items() if v != defaults[k]]
    command = "python -m flow_node.ros.security_policy" + (f" with {', '.join(changed)}" if changed else "")
    if a.client:
        client = client_interfaces(interfaces, a.namespace, a.name)
        nodes = [n for n in a.client_nodes.split(",") if n]
        return policy_xml(a.enclave or "/flow_client", [Profile("/", n, client) for n in nodes], command)
    enclave = a.enclave or resolve(a.name, a.namespace, a.name)  # the node's full name
    return policy_xml(enclave, [Profile(a.namespace, a.name, interfaces)], command)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m flow_node.ros.security_policy [options] > policy.xml``."""
    sys.stdout.write(render(sys.argv[1:] if argv is None else argv))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
