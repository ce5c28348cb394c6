"""The start-up security check: plain functions (environment, enclave directory, RMW) and, over real DDS, the
trap itself: ROS_SECURITY_ENABLE=true, Permissive, no enclave, on the venv's Fast DDS (built without
DDS-Security), where the node runs unsecured and must say so in /rosout and /diagnostics."""

from __future__ import annotations

from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rcl_interfaces.msg import Log
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from ros_helpers import Harness, wait_for

from flow_node.ros import security as sec

pytestmark = pytest.mark.ros  # rclpy over DDS: a node or a publisher in this process, or a node process

FILES = ["identity_ca.cert.pem", "cert.pem", "key.pem", "permissions_ca.cert.pem", "governance.p7s",
         "permissions.p7s"]


def settings(**env: str) -> sec.SecuritySettings:
    return sec.settings_from_env({"ROS_SECURITY_ENABLE": "true", **env})


def test_settings_follow_rcl() -> None:
    assert not sec.settings_from_env({}).enabled
    assert not sec.settings_from_env({"ROS_SECURITY_ENABLE": "True"}).enabled  # rcl compares with "true"
    s = settings(ROS_SECURITY_STRATEGY="Enforce", ROS_SECURITY_KEYSTORE="/ks")
    assert (s.enabled, s.enforce, s.keystore) == (True, True, "/ks")
    assert not settings(ROS_SECURITY_STRATEGY="enforce").enforce  # anything but "Enforce" is Permissive


def test_enclave_directory_and_override() -> None:
    assert sec.enclave_dir("/ks", "/flow_node") == Path("/ks/enclaves/flow_node")
    assert sec.enclave_dir("/ks", "/robot/flow_node") == Path("/ks/enclaves/robot/flow_node")
    assert sec.enclave_dir("/ks", "/") == Path("/ks/enclaves")  # rcl's default enclave
    assert sec.enclave_dir("/ks", "/flow_node", "/other") == Path("/ks/enclaves/other")


def test_missing_files(tmp_path: Path) -> None:
    assert sec.missing_files(tmp_path) == FILES
    for f in FILES[:3]:
        (tmp_path / f).write_text("x")
    assert sec.missing_files(tmp_path) == FILES[3:]
    (tmp_path / "key.pem").unlink()
    (tmp_path / "key.p11").write_text("pkcs11:object=key")  # a PKCS#11 key counts
    assert sec.missing_files(tmp_path) == FILES[3:]


def test_rmw_security_support() -> None:
    wheel = b"...This Fast DDS version doesn't have the security libraries\nPlease compile..."
    assert sec.rmw_has_security("rmw_fastrtps_cpp", [b"\x7fELF", wheel]) is False
    assert sec.rmw_has_security("rmw_fastrtps_cpp", [b"\x7fELF built with security"]) is True
    assert sec.rmw_has_security("rmw_cyclonedds_cpp", [wheel]) is True  # the mark is Fast DDS's
    assert sec.rmw_has_security("rmw_zenoh_cpp", []) is None


def test_assess_verdicts() -> None:
    enforce = settings(ROS_SECURITY_STRATEGY="Enforce", ROS_SECURITY_KEYSTORE="/ks")
    ok = sec.assess(enforce, "/flow_node", "rmw_cyclonedds_cpp", True, [])
    assert ok.secured is True and ok.problems == () and ok.summary == "secured (SROS2)"
    assert dict(ok.details)["enclave directory"] == "/ks/enclaves/flow_node"
    assert sec.assess(sec.settings_from_env({}), "/", "rmw_fastrtps_cpp", False, None).secured is None

    permissive = settings(ROS_SECURITY_KEYSTORE="/ks")  # strategy unset = Permissive
    trap = sec.assess(permissive, "/flow_node", "rmw_fastrtps_cpp", False, None)
    assert trap.secured is False and len(trap.problems) == 3
    assert "built without DDS-Security" in trap.problems[0]
    assert "enclave /flow_node not found (no directory /ks/enclaves/flow_node)" in trap.problems[1]
    assert "Permissive" in trap.problems[2] and trap.summary.startswith("ROS_SECURITY_ENABLE=true but the node runs "
                                                                        "UNSECURED")
    partial = sec.assess(permissive, "/", "rmw_cyclonedds_cpp", True, ["cert.pem", "key.pem"])
    assert partial.secured is False and "/ks/enclaves lacks cert.pem, key.pem" in partial.problems[0]
    unknown = sec.assess(enforce, "/flow_node", "rmw_zenoh_cpp", None, [])
    assert unknown.secured is False and "rmw_zenoh_cpp does not apply SROS2" in unknown.problems[0]
    assert len(unknown.problems) == 1  # Enforce: no Permissive advice
    nokeystore = sec.assess(settings(), "/flow_node", "rmw_cyclonedds_cpp", True, None)
    assert nokeystore.problems[0] == "ROS_SECURITY_KEYSTORE is not set"


def test_diagnostic_status_levels() -> None:
    enforce = settings(ROS_SECURITY_STRATEGY="Enforce", ROS_SECURITY_KEYSTORE="/ks")
    (ok,) = sec.statuses(sec.assess(enforce, "/e", "rmw_cyclonedds_cpp", True, []), "n", "cam")
    assert (ok.level, ok.name, ok.hardware_id) == (DiagnosticStatus.OK, "n: security", "cam")
    (warn,) = sec.statuses(sec.assess(enforce, "/e", "rmw_cyclonedds_cpp", True, None), "n", "cam")
    assert warn.level == DiagnosticStatus.WARN and "UNSECURED" in warn.message
    assert sec.statuses(sec.assess(sec.settings_from_env({}), "/", "x", None, None), "n", "cam") == []


def test_loaded_libraries_reads_the_process_maps(tmp_path: Path) -> None:
    maps = tmp_path / "maps"
    maps.write_text("7f00-7f01 r--p 00000000 08:01 1 /opt/ros/lib/librmw_fastrtps_shared_cpp.so\n"
                    "7f01-7f02 r-xp 00001000 08:01 1 /opt/ros/lib/librmw_fastrtps_shared_cpp.so\n"
                    "7f02-7f03 r--p 00000000 08:01 2 /usr/lib/libc.so.6\n7f03-7f04 rw-p 00000000 00:00 0\n")
    assert sec.loaded_libraries(("librmw_fastrtps",), str(maps)) == [
        Path("/opt/ros/lib/librmw_fastrtps_shared_cpp.so")]
    assert sec.loaded_libraries(("x",), str(tmp_path / "none")) == []


def test_permissive_trap_is_reported_over_dds(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """The venv's Fast DDS, security asked for, Permissive, no enclave: rcl starts the node unsecured; the node
    warns on /rosout (transient local: a late subscriber still gets it) and in a "security" diagnostic."""
    monkeypatch.setenv("ROS_SECURITY_ENABLE", "true")
    monkeypatch.setenv("ROS_SECURITY_STRATEGY", "Permissive")
    monkeypatch.setenv("ROS_SECURITY_KEYSTORE", str(tmp_path / "keystore"))  # no keystore at all
    h = Harness("/sec_trap", name="flow_trap")
    try:
        assert h.node.state().secured is False
        logs: list[Log] = []
        statuses: list[DiagnosticStatus] = []
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
        h.client.create_subscription(Log, "/rosout", logs.append, qos)
        h.client.create_subscription(DiagnosticArray, "/diagnostics", lambda m: statuses.extend(
            s for s in m.status if s.name == "flow_trap: security"), 10)
        log = wait_for(lambda: next((m for m in list(logs) if m.name.endswith("flow_trap") and "UNSECURED" in m.msg),
                                    None), 10.0, "the warning on /rosout")
        assert log.level == Log.WARN
        assert "rmw_fastrtps_cpp here is built without DDS-Security" in log.msg
        assert f"no directory {tmp_path}/keystore/enclaves" in log.msg and "Permissive" in log.msg
        st = wait_for(lambda: statuses and statuses[-1], 10.0, "the security diagnostic")
        assert st.level == DiagnosticStatus.WARN and st.message == log.msg
        values = {kv.key: kv.value for kv in st.values}
        assert (values["rmw"], values["strategy"], values["enclave"]) == ("rmw_fastrtps_cpp", "Permissive", "/")
    finally:
        h.close()
