"""The live node over real DDS (`make bench-node`), one mode per question; what each measures and why:
docs/node.md ("Threading, drops and latency", "Middleware") and BENCHMARKS.md. Results in bench/results/node/ (FILES).

    python -m bench.node latency [--frames 5] [--presets realtime quality] [--motion alternate|pan]
    python -m bench.node delivery [--seconds 10] [--repeats 2] [--variants default,profile,...]
    python -m bench.node security [--rounds 4] [--frames 30] [--size 320x240]    # in a security route

latency: per preset at 320x240 and 640x480, the node as its own process (bench.node_rig.ProcessRig): closed
loop (one frame in flight: latency, in-node overhead, time in publish, against the engine called here on the
same pair) then open loop at 30 Hz (output rate, share of the time solving). delivery: node, camera (30 Hz, best
effort) and a reliable subscriber as three processes per middleware variant (VARIANTS), interleaved; delivery =
received / published by the node. security: the closed loop secured (SROS2 Enforce, one enclave for node and
client) and plain, alternating per round, both on the route's Cyclone DDS.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig

from .common import REPO, run_record, write_json
from .node_rig import Frames, ProcessRig, stop

OUT = REPO / "bench" / "results" / "node"
FILES = {"latency": "node_latency.json", "delivery": "node_delivery.json", "security": "security_latency.json"}
SIZES = {"320x240": (240, 320), "640x480": (480, 640)}
_PROFILE = {"FASTRTPS_DEFAULT_PROFILES_FILE": str(REPO / "config" / "fastdds_localhost.xml")}
_LARGE = {"FASTDDS_BUILTIN_TRANSPORTS": "LARGE_DATA"}
# delivery variant -> (environment of the node and the camera, of the subscriber): Fast DDS as it comes, the
# package's profile everywhere or for the node only, Fast DDS's built-in LARGE_DATA (TCP + shared memory)
VARIANTS = {"default": ({}, {}), "profile": (_PROFILE, _PROFILE), "profile_node_only": (_PROFILE, {}),
            "large_data": (_LARGE, _LARGE)}
DELIVERY_SIZES = {"640x480": (480, 640), "1280x720": (720, 1280)}
NS, NODE = "/bench_delivery", "delivery_flow"
ENCLAVE = "/flow_bench"


def medians(loop: list[dict[str, float]]) -> dict[str, float]:
    """Per key of the closed loop's rows, its median; and ``outside_solve``: latency minus solve."""
    return {k: statistics.median(d[k] for d in loop) for k in loop[0]} | {
        "outside_solve": statistics.median(d["latency"] - d["solve"] for d in loop)}


def latency(preset: str, size: tuple[int, int], n: int, motion: str) -> dict[str, Any]:
    """One preset and size: closed loop of ``n`` flows, then the open loop for four solve times (>= 3 s)."""
    seq, cfg = Frames(*size, motion), FlowConfig.preset(preset)
    engine = FlowEstimator(cfg)
    engine.warmup()
    first = engine.estimate(seq.frame(0), seq.frame(1)).seconds
    rig = ProcessRig(preset)
    try:
        loop = rig.closed_loop(seq, n, 30.0 * first + 10.0, engine)
        tput = rig.open_loop(seq, n + 1, max(3.0, 4 * statistics.median(d["solve"] for d in loop)))
    finally:
        rig.close()
    m = medians(loop)
    return {"preset": preset, "config": cfg.to_dict(), "width": size[1], "height": size[0], "frames": n,
            "motion": motion, "backend": rig.backend, "node": "own process", "engine_solve_median_s": m["engine"],
            "node_solve_median_s": m["solve"], "latency_median_s": m["latency"],
            "latency_max_s": max(d["latency"] for d in loop), "node_overhead_median_s": m["node_overhead"],
            "node_overhead_ratio": m["node_overhead"] / m["solve"], "node_publish_median_s": m["node_publish"],
            "node_publish_ratio": m["node_publish"] / m["solve"],
            "end_to_end_overhead_ratio": (m["latency"] - m["solve"]) / m["solve"],
            "latency_vs_engine_ratio": m["latency"] / m["engine"],
            "aee_interior_px": m["aee"], "throughput": tput, "per_frame": loop}


def run_latency(args: argparse.Namespace) -> dict[str, Any]:
    results = []
    for preset in args.presets:
        for size in SIZES.values():
            r = latency(preset, size, args.frames, args.motion)
            tp = r["throughput"]
            results.append(r)
            print(f"{preset:9s} {r['width']}x{r['height']} {r['backend']}: engine {r['engine_solve_median_s']*1e3:8.1f}"
                  f" ms | latency {r['latency_median_s']*1e3:8.1f} ms (x{r['latency_vs_engine_ratio']:.3f}) | in-node"
                  f" overhead {100*r['node_overhead_ratio']:5.2f} % (publish {100*r['node_publish_ratio']:5.2f} %) |"
                  f" end-to-end overhead {100*r['end_to_end_overhead_ratio']:5.2f} % | throughput "
                  f"{tp['output_rate_hz']:.2f} Hz (solving {tp['solver_busy_fraction']:.2f}) | AEE "
                  f"{r['aee_interior_px']:.3f}", flush=True)
    return {"results": results}


def camera(size: str, seconds: float, rate: float = 30.0) -> None:
    """(delivery's camera process) Two alternating textured mono8 frames at ``rate`` Hz, best effort."""
    import rclpy
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import Image

    h, w = DELIVERY_SIZES[size]
    base = np.random.default_rng(0).integers(0, 256, (h + 8, w + 8), dtype=np.uint8)
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
        msg.header.stamp, msg.header.frame_id = node.get_clock().now().to_msg(), "bench"
        pub.publish(msg)
        k += 1
        time.sleep(max(0.0, start + k / rate - time.monotonic()))
    print(json.dumps({"sent": k}), flush=True)
    node.destroy_node()
    rclpy.shutdown()


def subscribe(seconds: float) -> None:
    """(delivery's subscriber process) Count ~/flow messages (rclpy's default QoS: reliable, keep last 10) and
    read the node's counters on /diagnostics until SIGINT or ``seconds``; print one JSON line."""
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

    def on_diag(msg: DiagnosticArray) -> None:
        for st in (s for s in msg.status if s.name == f"{NODE}: optical flow"):
            diag.clear()
            diag.update({kv.key: kv.value for kv in st.values}, _message=st.message)
            if diag["solve time mean (ms)"] != "n/a":
                solve_ms.append(float(diag["solve time mean (ms)"]))

    node.create_subscription(Image, f"{NS}/{NODE}/flow",
                             lambda m: got.append(m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec), 10)
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


def delivery(size: str, variant: str, seconds: float) -> dict[str, Any]:
    """One run: node, subscriber, then the camera for ``seconds``; the counts after everything settled."""
    node_env, sub_env = ({**os.environ, **e} for e in VARIANTS[variant])
    me = [sys.executable, "-m", "bench.node", "delivery"]

    def popen(args: list[str], env: dict[str, str]) -> subprocess.Popen:
        return subprocess.Popen(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    node = popen([sys.executable, "-m", "flow_node.ros.node", "--ros-args", "-r", f"__ns:={NS}",
                  "-r", f"__node:={NODE}", "-r", f"image:={NS}/image"], node_env)
    sub = popen([*me, "--subscribe", "--seconds", str(seconds + 120)], sub_env)
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
    return {"size": size, "variant": variant, "camera_frames": sent, "node_received": int(d.get("frames received", 0)),
            "node_published": published, "subscriber_received": got["received"],
            "delivery": got["received"] / published if published else None,
            "node_solve_ms_median": got["solve_ms_median"], "backend": d.get("backend")}


def run_delivery(args: argparse.Namespace) -> dict[str, Any]:
    runs: list[dict[str, Any]] = []
    for rep in range(args.repeats):
        for size in DELIVERY_SIZES:
            for variant in args.variants.split(","):
                runs.append(delivery(size, variant, args.seconds) | {"repeat": rep})
                print(json.dumps(runs[-1]), flush=True)
    return {"seconds": args.seconds, "rate_hz": 30.0, "runs": runs}


def make_keystore(root: Path) -> Path:
    """A keystore (sros2's API; the domain from ROS_DOMAIN_ID) with one enclave for the bench's node
    (/bench/flow_bench) and client (/bench/bench_client), permissions generated by flow_node.ros.security_policy."""
    from sros2.keystore import create_enclave, create_keystore, create_permission

    from flow_node.ros import security_policy as sp

    node = sp.node_interfaces()
    client = sp.client_interfaces(node, "/bench", ProcessRig.NAME)
    policy = root / "bench_policy.xml"
    policy.write_text(sp.policy_xml(ENCLAVE, [sp.Profile("/bench", ProcessRig.NAME, node),
                                              sp.Profile("/bench", "bench_client", client)], "bench.node security"))
    ks = root / "keystore"
    create_keystore(ks)
    create_enclave(ks, ENCLAVE)
    create_permission(ks, ENCLAVE, policy)
    return ks


def run_security(args: argparse.Namespace) -> dict[str, Any]:
    """Rounds of secured and plain closed loops (the order alternating); per round medians, and their medians.
    Setting the security environment is process-wide state: only this mode does it."""
    if os.environ.get("RMW_IMPLEMENTATION") != "rmw_cyclonedds_cpp":
        raise SystemExit("run it in a security route's environment (source DIR/activate.sh; source DIR/secure.sh)")
    w, h = (int(x) for x in args.size.split("x"))
    engine = FlowEstimator(FlowConfig.preset(args.preset))
    engine.warmup()
    rounds: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        secure = {"ROS_SECURITY_ENABLE": "true", "ROS_SECURITY_STRATEGY": "Enforce",
                  "ROS_SECURITY_KEYSTORE": str(make_keystore(Path(tmp))), "ROS_SECURITY_ENCLAVE_OVERRIDE": ENCLAVE}
        for r in range(args.rounds):
            res: dict[str, Any] = {}
            for name in ("secured", "plain")[:: 1 if r % 2 == 0 else -1]:
                for k in secure:
                    os.environ.pop(k, None)
                os.environ.update(secure if name == "secured" else {})
                rig = ProcessRig(args.preset)
                try:
                    res[name] = medians(rig.closed_loop(Frames(h, w), args.frames, 30.0, engine))
                finally:
                    rig.close()
            for k in secure:
                os.environ.pop(k, None)
            s, p = res["secured"], res["plain"]
            res |= {"latency_cost_s": s["latency"] - p["latency"], "latency_ratio": s["latency"] / p["latency"]}
            rounds.append(res)
            print(f"round {r}: " + ", ".join(f"{k} secured {s[k]*1e3:.2f} ms, plain {p[k]*1e3:.2f} ms"
                                             for k in ("latency", "outside_solve", "node_publish")), flush=True)
    summary = {k: statistics.median(rr[k] for rr in rounds) for k in ("latency_cost_s", "latency_ratio")}
    for part in ("outside_solve", "node_publish", "solve"):
        summary[f"{part}_cost_s"] = statistics.median(rr["secured"][part] - rr["plain"][part] for rr in rounds)
    print("median over rounds: " + ", ".join(f"{k} {v:.5f}" for k, v in summary.items()))
    return {"rmw": os.environ["RMW_IMPLEMENTATION"], "size": args.size, "preset": args.preset, "summary": summary,
            "rounds": rounds}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.node", description=__doc__.splitlines()[0])
    modes = ap.add_subparsers(dest="mode", required=True)
    lat = modes.add_parser("latency")
    lat.add_argument("--frames", type=int, default=5, help="flows per case in the closed loop")
    lat.add_argument("--presets", nargs="+", default=["realtime", "quality"])
    lat.add_argument("--motion", choices=("alternate", "pan"), default="alternate",
                     help="frames back and forth between two, or a steady pan (a stream: stream presets)")
    dlv = modes.add_parser("delivery")
    dlv.add_argument("--seconds", type=float, default=10.0)
    dlv.add_argument("--repeats", type=int, default=2)
    dlv.add_argument("--variants", default=",".join(VARIANTS))
    dlv.add_argument("--camera", choices=tuple(DELIVERY_SIZES), help=argparse.SUPPRESS)
    dlv.add_argument("--subscribe", action="store_true", help=argparse.SUPPRESS)
    sec = modes.add_parser("security")
    sec.add_argument("--rounds", type=int, default=4)
    sec.add_argument("--frames", type=int, default=30, help="flows per condition and round")
    sec.add_argument("--size", default="320x240", help="WxH")
    sec.add_argument("--preset", default="realtime")
    for p in (lat, dlv, sec):
        p.add_argument("--out", type=Path, default=None, help=f"default {OUT.relative_to(REPO)}/{FILES}")
    args = ap.parse_args(argv)
    if args.mode == "delivery" and (args.camera or args.subscribe):
        camera(args.camera, args.seconds) if args.camera else subscribe(args.seconds)
        return 0
    head = run_record("bench.node", argv)
    res = {"latency": run_latency, "delivery": run_delivery, "security": run_security}[args.mode](args)
    write_json(args.out or OUT / FILES[args.mode], {"meta": head, **res})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
