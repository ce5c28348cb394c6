"""The node under input rates from camera-like to a flood, spun by rclpy's single- or multi-threaded executor.

    .venv/bin/python -m bench.node_flood [--rates 30 100 500] [--presets realtime quality] [--seconds 6]
                                         [--repeats 1] [--plain] [--out bench/results/node_flood.json]

The node runs as its own process (as in bench.node_latency), once with ``SingleThreadedExecutor`` (what
``rclpy.spin`` in the node's main() uses) and once with ``MultiThreadedExecutor()`` (default thread count),
which is what a user composing several Python nodes into one process would likely pick. For each preset at
320x240 mono8 and each rate, frames are published open loop for ``--seconds``; reported: frames the node's
callback received per second, flows it published per second, and the mean solve time under that load
(from its /diagnostics) against the engine's solve time measured here just before (the
peer of the ratio). ``--plain`` first runs rclpy alone the same way: a subscriber process that only counts
the frames it takes, to tell the executor's limits from the node's. The machine is shared: compare the
ratios, not absolute times.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Image

from bench.node_latency import ProcessRig, frames, image_msg
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig
from flow_node.process import keep_freed_memory
from flow_node.ros.node import FlowNode

EXECUTORS = ("single", "multi")
SIZE = (240, 320)
PLAIN_TOPIC = "/bench_plain/image"


def serve(executor: str, args: list[str], plain: bool = False) -> int:
    """The node's main() with the executor chosen: ``single`` (as rclpy.spin) or ``multi``. ``plain``: no
    flow_node at all, a node whose subscription (the same QoS) only counts; prints the count as JSON at exit."""
    rclpy.init(args=args)
    if plain:
        node, count = Node("plain_subscriber"), [0]
        node.create_subscription(Image, PLAIN_TOPIC, lambda _: count.__setitem__(0, count[0] + 1),
                                 QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
    else:
        keep_freed_memory()
        node = FlowNode()
    ex = SingleThreadedExecutor() if executor == "single" else MultiThreadedExecutor()
    ex.add_node(node)
    try:
        ex.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if plain:
            print(json.dumps({"received": count[0]}), flush=True)
        ex.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


def run_plain(executor: str, rate: float, seconds: float) -> dict[str, Any]:
    """Frames at ``rate`` to the plain subscriber process: what rclpy's executor alone takes."""
    proc = subprocess.Popen([sys.executable, "-m", "bench.node_flood", "--serve-plain", executor],
                            stdout=subprocess.PIPE, text=True)
    ctx = Context()
    rclpy.init(context=ctx)
    try:
        pub = Node("plain_publisher", context=ctx).create_publisher(Image, PLAIN_TOPIC, 10)
        end = time.monotonic() + 60.0
        while pub.get_subscription_count() == 0 and time.monotonic() < end:
            time.sleep(0.05)
        time.sleep(0.5)
        msg = image_msg(frames(*SIZE)[0], 1)
        start, k = time.perf_counter(), 0
        while time.perf_counter() - start < seconds:
            pub.publish(msg)
            k += 1
            time.sleep(max(0.0, start + k / rate - time.perf_counter()))
        elapsed = time.perf_counter() - start
        time.sleep(0.5)
    finally:
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=30)
        rclpy.try_shutdown(context=ctx)
    if not out.strip():
        raise RuntimeError(f"the plain subscriber ({executor}) printed no count (exit code {proc.returncode})")
    received = json.loads(out.strip().splitlines()[-1])["received"]
    return {"executor": executor, "rate_hz": rate, "sent_rate_hz": k / elapsed, "received_rate_hz": received / elapsed}


def run(preset: str, executor: str, rate: float, seconds: float) -> dict[str, Any]:
    f0, f1 = frames(*SIZE)
    engine = FlowEstimator(FlowConfig.preset(preset))
    engine.warmup()
    engine_s = min(engine.estimate(f0, f1).seconds for _ in range(3))
    rig = ProcessRig(preset, (sys.executable, "-m", "bench.node_flood", "--serve", executor))
    try:
        tp = rig.open_loop(f0, f1, seconds, rate)
    finally:
        rig.close()
    solve = tp["node_solve_s"] / tp["node_outputs"] if tp["node_outputs"] else None
    return {"preset": preset, "executor": executor, "rate_hz": rate, "width": SIZE[1], "height": SIZE[0],
            "backend": rig.backend, "engine_solve_s": engine_s, "node_solve_mean_s": solve,
            "solve_vs_engine_ratio": None if solve is None else solve / engine_s,
            "received_rate_hz": tp["received"] / tp["seconds"], "sent_rate_hz": tp["published"] / tp["seconds"],
            "flows_rate_hz": tp["node_outputs"] / tp["seconds"],
            "throughput": tp}


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] in (["--serve"], ["--serve-plain"]):
        return serve(argv[1], argv[2:], plain=argv[0] == "--serve-plain")
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rates", type=float, nargs="+", default=[30.0, 100.0, 500.0])
    ap.add_argument("--presets", nargs="*", default=["realtime", "quality"], help="none: --plain only")
    ap.add_argument("--executors", nargs="+", choices=EXECUTORS, default=list(EXECUTORS))
    ap.add_argument("--seconds", type=float, default=6.0, help="open-loop publishing time per case")
    ap.add_argument("--repeats", type=int, default=1, help="runs of each case (the executors alternate)")
    ap.add_argument("--out", default="bench/results/node_flood.json")
    ap.add_argument("--plain", action="store_true", help="also rclpy alone: a subscriber that only counts")
    args = ap.parse_args(argv)
    results, plain = [], []
    for rate in args.rates if args.plain else []:
        for executor in args.executors * args.repeats:
            r = run_plain(executor, rate, args.seconds)
            plain.append(r)
            print(f"plain     {executor:6s} {rate:5.0f} Hz: sent {r['sent_rate_hz']:6.1f}/s"
                  f" | received {r['received_rate_hz']:6.1f}/s", flush=True)
    for preset in args.presets:
        for rate in args.rates:
            for executor in args.executors * args.repeats:
                r = run(preset, executor, rate, args.seconds)
                results.append(r)
                solve = "no flow" if r["node_solve_mean_s"] is None else (
                    f"{r['node_solve_mean_s'] * 1e3:8.1f} ms (x{r['solve_vs_engine_ratio']:.2f})")
                print(f"{preset:9s} {executor:6s} {rate:5.0f} Hz {r['backend']}: sent {r['sent_rate_hz']:6.1f}/s"
                      f" | received {r['received_rate_hz']:6.1f}/s | flows {r['flows_rate_hz']:6.1f}/s"
                      f" | engine {r['engine_solve_s'] * 1e3:7.1f} ms | solve under load {solve}", flush=True)
    meta = {"command": "python -m bench.node_flood " + " ".join(argv), "python": platform.python_version(),
            "machine": platform.machine(), "cpus": os.cpu_count(),
            "date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps({"meta": meta, "plain": plain, "results": results}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
