"""The node under SROS2 Enforce with the shipped policy, over a real DDS with DDS-Security (Cyclone DDS and its
security plugins): an authorised client gets flow and can reset the node and set its parameters (service and
``ros2 param set``); an unauthenticated client gets nothing; a client denied the image topic cannot feed it;
every row of the policy is needed.

The venv's Fast DDS has no DDS-Security, so this runs in the environment of a security route: a folder built
by ``../shared/tools/ros2-toolchain DIR`` and ``ros2-security DIR`` (``.ci/security`` builds one and runs
this file), given as ``FLOW_NODE_SECURITY_ROUTE=DIR``; without it the tests are skipped. The node and the
clients run as processes of that environment (test/security_client.py); this process only orchestrates.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
from small_frames import PARAMS

from flow_node.ros import security_policy as sp

ROUTE = os.environ.get("FLOW_NODE_SECURITY_ROUTE", "")
pytestmark = [pytest.mark.ros, pytest.mark.skipif(
    not ROUTE,
    reason="no SROS2 route: the venv's Fast DDS has no DDS-Security; set FLOW_NODE_SECURITY_ROUTE to a folder "
           "built by ros2-toolchain + ros2-security (.ci/security does) to run these")]
ROOT = Path(__file__).resolve().parents[1]
CLIENT = str(ROOT / "test" / "security_client.py")
GT = (1.5, -0.75)  # ros_helpers.GT, the pair the client sends
NODE_ARGS = [a for k, v in PARAMS.items() for a in ("-p", f"{k}:={v}")]


def route_env() -> dict[str, str]:
    """The environment of DIR/activate.sh + DIR/secure.sh, with this run's domain and localhost discovery."""
    assert (Path(ROUTE) / "secure.sh").is_file(), f"FLOW_NODE_SECURITY_ROUTE={ROUTE}: not a built route (no secure.sh)"
    script = f'set +u; source "{ROUTE}/activate.sh" >/dev/null; source "{ROUTE}/secure.sh"; env -0'
    out = subprocess.run(["bash", "-c", script], check=True, capture_output=True, env={
        "PATH": os.environ.get("PATH", "/usr/bin:/bin"), "HOME": os.environ.get("HOME", "/tmp")}).stdout
    env = dict(kv.split("=", 1) for kv in out.decode().split("\0") if "=" in kv)
    env.update(ROS_DOMAIN_ID=os.environ["ROS_DOMAIN_ID"], ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               PYTHONPATH=os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH", "")) if p),
               PYTHONUNBUFFERED="1")
    return env


def run(cmd: list[str], env: dict[str, str], timeout: float = 120.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)


def client(role: list[str], env: dict[str, str]) -> dict:
    proc = run(["python", CLIENT, *role], env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def intruder_policy() -> str:
    """The client policy without the right to publish the image topic (everything else kept)."""
    client_rows = sp.client_interfaces(sp.node_interfaces(), "/", "flow_node")
    rows = [i for i in client_rows if not (i.access == "publish" and i.name == "/image")]
    assert len(rows) == len(client_rows) - 1
    return sp.policy_xml("/flow_intruder", [sp.Profile("/", "flow_client", rows)], "test: intruder")


def drop_policy(enclave: str, drop: sp.Interface) -> str:
    rows = [i for i in sp.node_interfaces() if i != drop]
    return sp.policy_xml(enclave, [sp.Profile("/", "flow_node", rows)], "test: one row dropped")


SROS2_API = """
import sys
from pathlib import Path
from sros2.keystore import create_enclave, create_permission
ks = Path(sys.argv[1])
for policy in sys.argv[2:]:
    enclave = "/" + Path(policy).stem
    create_enclave(ks, enclave)
    create_permission(ks, enclave, Path(policy))
"""


@pytest.fixture(scope="module")
def secure(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    """A keystore (``ros2 security``, as docs/security.md does it) with the node's enclave (the shipped policy),
    a client's and an intruder's, plus one enclave per dropped row (sros2's API, one process); returns the
    secured environment (Enforce)."""
    env = route_env()
    tmp = tmp_path_factory.mktemp("sros2")
    ks = tmp / "keystore"
    (tmp / "flow_client.xml").write_text(sp.render(["--client"]))
    (tmp / "flow_intruder.xml").write_text(intruder_policy())
    verbs = [["create_keystore", str(ks)]] + [
        v for e, policy in (("/flow_node", ROOT / "config" / "flow_node.policy.xml"),
                            ("/flow_client", tmp / "flow_client.xml"), ("/flow_intruder", tmp / "flow_intruder.xml"))
        for v in (["create_enclave", str(ks), e], ["create_permission", str(ks), e, str(policy)])]
    for verb in verbs:
        proc = run(["ros2", "security", *verb], env)
        assert proc.returncode == 0, f"ros2 security {' '.join(verb)}: {proc.stdout[-800:]} {proc.stderr[-1500:]}"
    drops = []
    for k, row in enumerate(sp.node_interfaces()):
        drops.append(tmp / "drops" / f"drop{k}.xml")
        drops[-1].parent.mkdir(exist_ok=True)
        drops[-1].write_text(drop_policy(f"/drop{k}", row))
    proc = run(["python", "-c", SROS2_API, str(ks), *map(str, drops)], env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return {**env, "ROS_SECURITY_KEYSTORE": str(ks), "ROS_SECURITY_ENABLE": "true",
            "ROS_SECURITY_STRATEGY": "Enforce"}


@pytest.fixture(scope="module")
def node(secure: dict[str, str], tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """The node, started as ``ros2 run`` would, in its enclave; yields its log file."""
    log = tmp_path_factory.mktemp("node") / "node.log"
    with log.open("w") as out:
        proc = subprocess.Popen(["python", "-m", "flow_node.ros.node", "--ros-args", "--enclave", "/flow_node",
                                 *NODE_ARGS], env=secure, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        end = time.monotonic() + 60.0
        while "engine warm-up" not in log.read_text():
            assert proc.poll() is None, f"the node exited with {proc.returncode}:\n{log.read_text()[-3000:]}"
            assert time.monotonic() < end, f"the node did not start:\n{log.read_text()[-3000:]}"
            time.sleep(0.2)
        yield log
    finally:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def test_node_under_enforce_serves_only_the_authorised_client(node: Path, secure: dict[str, str]) -> None:
    started = "secured (SROS2): enclave /flow_node, enclave override none, rmw rmw_cyclonedds_cpp, strategy Enforce"
    assert started in node.read_text()

    unauthenticated = {k: v for k, v in secure.items() if not k.startswith("ROS_SECURITY_")}
    stranger = client(["feed", "4"], unauthenticated)
    assert stranger["publisher_error"] is None  # it may publish on its own, but nobody secure listens
    assert (stranger["flows"], stranger["node_visible"], stranger["image_subscribers"]) == (0, False, 0)
    assert stranger["diagnostics"] == {}  # not even the node's health leaks

    intruder = client(["feed", "2", "--ros-args", "--enclave", "/flow_intruder"], secure)
    assert intruder["publisher_error"] is not None and "rt/image" in intruder["publisher_error"]
    assert intruder["flows"] == 0 and intruder["node_visible"]  # authenticated: it sees the node, cannot feed it

    friend = client(["feed", "6", "--ros-args", "--enclave", "/flow_client"], secure)
    assert friend["publisher_error"] is None and friend["node_visible"] and friend["image_subscribers"] == 1
    assert len(friend["flow_means"]) >= 3, friend
    u, v = sorted(friend["flow_means"])[len(friend["flow_means"]) // 2]  # median pair
    assert abs(u - GT[0]) < 0.3 and abs(v - GT[1]) < 0.3, friend["flow_means"]
    assert friend["reset"][0] is True and friend["set_alpha"] == [True] and friend["alpha"] == 0.75
    # nothing the stranger or the intruder published reached the node: before the client fed it, it had none
    assert friend["received_before"] == "0", friend["received_before"]
    assert int(friend["diagnostics"]["flow_node: optical flow"]["values"]["frames received"]) > 0
    security = friend["diagnostics"]["flow_node: security"]
    assert security["level"] == 0 and security["message"] == "secured (SROS2)"
    assert "UNSECURED" not in node.read_text()


def test_ros2_param_set_from_the_client_enclave(node: Path, secure: dict[str, str]) -> None:
    env = {**secure, "ROS_SECURITY_ENCLAVE_OVERRIDE": "/flow_client"}  # the ros2 CLI takes no --ros-args
    proc = run(["ros2", "param", "set", "--no-daemon", "/flow_node", "alpha", "0.5"], env)
    assert "Set parameter successful" in proc.stdout, proc.stdout + proc.stderr  # it exits 0 on failure too
    proc = run(["ros2", "param", "get", "--no-daemon", "/flow_node", "alpha"], env)
    assert "Double value is: 0.5" in proc.stdout, proc.stdout + proc.stderr
    proc = run(["ros2", "param", "set", "--no-daemon", "/flow_node", "alpha", "0.0"], env)
    assert "Setting parameter failed: alpha: must be > 0" in proc.stderr, proc.stdout + proc.stderr
    denied = {**secure, "ROS_SECURITY_ENCLAVE_OVERRIDE": "/flow_intruder"}  # no parameter services for it
    proc = run(["ros2", "param", "get", "--no-daemon", "/flow_node", "alpha"], denied)
    assert "Double value" not in proc.stdout


def test_every_row_of_the_policy_is_needed(secure: dict[str, str]) -> None:
    """Without any one of its rows (Enforce) the node does not start; with all of them it does."""
    rows = sp.node_interfaces()
    enclaves = ["/flow_node", *(f"/drop{k}" for k in range(len(rows)))]
    # one process per enclave: in one process, a participant whose node failed spoils the next one's checks
    with ThreadPoolExecutor(3) as pool:
        reports = list(pool.map(lambda e: client(["start", e], secure), enclaves))
    report = {e: r[e] for e, r in zip(enclaves, reports, strict=True)}
    assert report["/flow_node"] is None, report["/flow_node"]
    for k, row in enumerate(rows):
        error = report[f"/drop{k}"]
        assert error is not None, f"the node started without {row.name} in its policy"
        dds = sp.resolve(row.name, "/", "flow_node")
        if row.access == "reply":
            assert f"[rr{dds}Reply]" in error, f"{row.name}: {error}"
        elif row.access == "publish":
            assert f"[rt{dds}]" in error, f"{row.name}: {error}"
        else:  # the subscription's error text is lost in rcl ("invalid allocator"); it fails all the same
            assert "subscription" in error, f"{row.name}: {error}"


if __name__ == "__main__":
    sys.exit(pytest.main([__file__, "-v"]))
