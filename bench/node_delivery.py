"""Delivery of ~/flow to a reliable subscriber in another process, at VGA and 720p, per middleware setting.

    .venv/bin/python -m bench.node_delivery [--seconds 10] [--repeats 2] [--out bench/results/node/node_delivery.json]

Three processes per run, all with the same middleware environment: the node (``python -m flow_node.ros.node``,
its default realtime preset), a camera (this module's ``--camera``: mono8 frames at 30 Hz, best effort) and a
subscriber (``--subscribe``: rclpy's default QoS, reliable, keep last 10, counting the ~/flow messages and
reading the node's own "frames published" on /diagnostics). Delivery = received / published by the node, so
frames the node drops because it is busy do not count against the middleware. Variants, interleaved:

* ``default``: Fast DDS as it comes (shared memory and UDP transports, 512 KB shared-memory segments);
* ``profile``: config/fastdds_localhost.xml (shared memory with 32 MB segments, UDP kept for discovery and
  other hosts), given to every process by FASTRTPS_DEFAULT_PROFILES_FILE;
* ``profile_node_only``: the profile for the node (and camera) only, the subscriber as it comes;
* ``large_data``: Fast DDS's built-in ``FASTDDS_BUILTIN_TRANSPORTS=LARGE_DATA`` (TCP + shared memory).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from .common import REPO, run_record, write_json
from .node_rig import stop

PROFILE = REPO / "config" / "fastdds_localhost.xml"
# variant -> (environment of the node and the camera, environment of the subscriber)
_PROFILE_ENV = {"FASTRTPS_DEFAULT_PROFILES_FILE": str(PROFILE)}
VARIANTS: dict[str, tuple[dict[str, str], dict[str, str]]] = {
    "default": ({}, {}),
    "profile": (_PROFILE_ENV, _PROFILE_ENV),
    "profile_node_only": (_PROFILE_ENV, {}),
    "large_data": ({"FASTDDS_BUILTIN_TRANSPORTS": "LARGE_DATA"}, {"FASTDDS_BUILTIN_TRANSPORTS": "LARGE_DATA"}),
}
SIZES = {"640x480": (480, 640), "1280x720": (720, 1280)}
NODE = "delivery_flow"
NS = "/bench_delivery"


def camera(size: str, rate: float, seconds: float) -> int:
    """Publish two alternating textured mono8 frames at ``rate`` Hz for ``seconds`` (best effort, depth 1)."""
    import rclpy
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import Image

    h, w = SIZES[size]
    rng = np.random.default_rng(0)
    base = rng.integers(0, 256, (h + 8, w + 8), dtype=np.uint8)
    frames = [np.ascontiguousarray(base[4:-4, 4:-4]), np.ascontiguousarray(base[5:-3, 6:-2])]
    rclpy.init(args=[])
    node = rclpy.create_node("delivery_camera", namespace=NS)
    pub = node.create_publisher(Image, f"{NS}/image", qos_profile_sensor_data)
    end = time.monotonic() + 60.0
    while pub.get_subscription_count() == 0 and time.monotonic() < end:
        time.sleep(0.05)
    start, k = time.monotonic(), 0
    while time.monotonic() < start + seconds:
        msg = Image(height=h, width=w, encoding="mono8", step=w)
        msg.data = frames[k % 2].tobytes()
        msg.header.stamp = node.get_clock().now().to_msg()
        msg.header.frame_id = "bench"
        pub.publish(msg)
        k += 1
        time.sleep(max(0.0, start + k / rate - time.monotonic()))
    print(json.dumps({"sent": k}), flush=True)
    node.destroy_node()
    rclpy.shutdown()
    return 0


def subscribe(seconds: float) -> int:
    """Count ~/flow messages (reliable, keep last 10) and read the node's counters on /diagnostics until
    SIGINT or ``seconds``; print one JSON line."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions
    from sensor_msgs.msg import Image

    signal.signal(signal.SIGINT, signal.default_int_handler)  # even when started with SIGINT ignored (nohup)
    rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("delivery_subscriber")
    got: list[int] = []
    diag: dict[str, str] = {}
    solve_ms: list[float] = []  # per diagnostics window that solved

    def on_flow(msg: Image) -> None:
        got.append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)

    def on_diag(msg: DiagnosticArray) -> None:
        for st in msg.status:
            if st.name == f"{NODE}: optical flow":
                diag.clear()
                diag.update({kv.key: kv.value for kv in st.values}, _message=st.message)
                if diag["solve time mean (ms)"] != "n/a":
                    solve_ms.append(float(diag["solve time mean (ms)"]))

    node.create_subscription(Image, f"{NS}/{NODE}/flow", on_flow, 10)
    node.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 10)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    end = time.monotonic() + seconds
    try:
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)
    except KeyboardInterrupt:
        pass
    print(json.dumps({"received": len(got), "unique": len(set(got)), "diagnostics": diag,
                      "solve_ms_median": float(np.median(solve_ms)) if solve_ms else None}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


def _popen(args: list[str], env: dict[str, str]) -> subprocess.Popen:
    return subprocess.Popen(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)


def run(size: str, variant: str, seconds: float) -> dict[str, Any]:
    """One run: node, subscriber, then camera for ``seconds``; the counts after everything settled."""
    node_env, sub_env = ({**os.environ, **e} for e in VARIANTS[variant])
    me = [sys.executable, "-m", "bench.node_delivery"]
    node = _popen([sys.executable, "-m", "flow_node.ros.node", "--ros-args", "-r", f"__ns:={NS}",
                   "-r", f"__node:={NODE}", "-r", f"image:={NS}/image"], node_env)
    sub = _popen([*me, "--subscribe", "--seconds", str(seconds + 120)], sub_env)
    sent = None
    try:
        time.sleep(5.0)  # node warm-up and discovery
        cam = subprocess.run([*me, "--camera", size, "--seconds", str(seconds)], env=node_env,
                             capture_output=True, text=True, timeout=seconds + 90)
        sent = json.loads(cam.stdout.strip().splitlines()[-1])["sent"]
        time.sleep(3.0)  # the last flows and a diagnostics message after them
    except (subprocess.TimeoutExpired, IndexError):
        pass  # recorded as a failed run (camera_frames null)
    finally:
        sub_out, _ = stop(sub)
        stop(node)
    got = json.loads(sub_out.strip().splitlines()[-1])
    d = got["diagnostics"]
    published = int(d.get("frames published", 0))
    return {"size": size, "variant": variant, "camera_frames": sent,
            "node_received": int(d.get("frames received", 0)), "node_published": published,
            "subscriber_received": got["received"], "delivery": got["received"] / published if published else None,
            "node_solve_ms_median": got["solve_ms_median"], "backend": d.get("backend")}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--variants", default=",".join(VARIANTS))
    p.add_argument("--out", type=Path, default=REPO / "bench/results/node/node_delivery.json")
    p.add_argument("--camera", choices=tuple(SIZES), help=argparse.SUPPRESS)
    p.add_argument("--subscribe", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.camera:
        return camera(args.camera, 30.0, args.seconds)
    if args.subscribe:
        return subscribe(args.seconds)
    runs, head = [], run_record("bench.node_delivery", argv)
    for rep in range(args.repeats):
        for size in SIZES:
            for variant in args.variants.split(","):
                r = run(size, variant, args.seconds)
                r["repeat"] = rep
                runs.append(r)
                print(json.dumps(r), flush=True)
                write_json(args.out, {**head, "seconds": args.seconds, "rate_hz": 30.0, "runs": runs})  # every run
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
