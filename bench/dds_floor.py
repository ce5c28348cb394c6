"""The transport floor under the node's latency: plain rclpy, no flow_node code. An echo process republishes
every ``sensor_msgs/Image`` it receives on ``/dds_floor/ping`` to ``/dds_floor/pong``; this process publishes
one message at a time and times the round trip (two hops, as a frame in and its flow out are).

    .venv/bin/python -m bench.dds_floor --out bench/results/dds_floor.json

Sizes: a 1 kB message, a 320x240 mono8 frame (77 kB), a 320x240 32FC2 flow (614 kB) and a 640x480 one
(2.4 MB). Reliable QoS, depth 10 both ways (the node's outputs are reliable), the RMW the venv has.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

SIZES = (1_000, 320 * 240, 320 * 240 * 8, 640 * 480 * 8)


def echo() -> None:
    """The echo side (run as its own process)."""
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from sensor_msgs.msg import Image

    rclpy.init()
    node = rclpy.create_node("dds_floor_echo")
    pub = node.create_publisher(Image, "/dds_floor/pong", 10)
    node.create_subscription(Image, "/dds_floor/ping", pub.publish, 10)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def round_trips(sizes: tuple[int, ...], count: int) -> dict[str, Any]:
    """Median, min and max round trip (ms) per message size in bytes, one message in flight at a time."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import Image

    rclpy.init()
    node = rclpy.create_node("dds_floor_client")
    pub = node.create_publisher(Image, "/dds_floor/ping", 10)
    got: list[float] = []
    node.create_subscription(Image, "/dds_floor/pong", lambda _m: got.append(time.perf_counter()), 10)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    out: dict[str, Any] = {}
    try:
        deadline = time.monotonic() + 30
        while (pub.get_subscription_count() == 0 or node.count_publishers("/dds_floor/pong") == 0) \
                and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(1.0)  # discovery settles
        for size in sizes:
            msg = Image(height=1, width=size, encoding="mono8", step=size, data=bytes(size))
            rtts = []
            for _ in range(count + 3):  # the first three warm up
                before = len(got)
                t0 = time.perf_counter()
                pub.publish(msg)
                end = t0 + 2.0
                while len(got) == before and time.perf_counter() < end:
                    time.sleep(0.0005)
                if len(got) > before:
                    rtts.append(1e3 * (got[-1] - t0))
                time.sleep(0.03)  # about a 30 Hz camera's spacing
            kept = rtts[3:]
            out[str(size)] = {"round_trip_ms_median": float(np.median(kept)), "min": min(kept), "max": max(kept),
                              "received": len(rtts), "sent": count + 3, "per_message": kept}
            print(f"{size:>9} bytes: round trip median {np.median(kept):6.2f} ms (min {min(kept):.2f}, "
                  f"max {max(kept):.2f})", flush=True)
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--count", type=int, default=30, help="round trips per size")
    p.add_argument("--out", type=Path, default=Path("bench/results/dds_floor.json"))
    p.add_argument("--echo", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.echo:
        echo()
        return 0
    proc = subprocess.Popen([sys.executable, "-m", "bench.dds_floor", "--echo"])
    try:
        results = round_trips(SIZES, args.count)
    finally:
        proc.terminate()
        proc.wait(timeout=10)
    from .common import machine, write_json

    write_json(args.out, {"command": "python -m bench.dds_floor " + " ".join(sys.argv[1:]), "machine": machine(),
                          "date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "results": results})
    print(json.dumps({k: round(v["round_trip_ms_median"], 2) for k, v in results.items()}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
