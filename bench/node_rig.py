"""The live node as its own process (``python -m flow_node.ros.node``, as ``ros2 run`` starts it) and an rclpy
client beside it in a private context, spun by one executor thread: what bench.node and bench.fuzz_node share.

The client publishes frames to the node's input and records its ~/flow messages (with their arrival time) and
its /diagnostics windows (key -> value, plus ``_message``). ``ProcessRig`` adds the closed loop (one frame in
flight) and the open loop (frames at 30 Hz) of bench.node's latency and security modes.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from typing import IO, Any

import cv2
import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import Image
from std_msgs.msg import Header

from flow_node.core.api import FlowEstimator
from flow_node.pipeline.codec import array_to_image_fields, image_to_array
from flow_node.ros.messages import image_msg as ros_image_msg

NODE_COMMAND = (sys.executable, "-m", "flow_node.ros.node")
WARMING = "warming up the engine"  # the node's diagnostics message until its engine is warm
SHIFT = (2.0, 1.0)  # (u, v) px between ProcessRig's frames


def wait(pred: Callable[[], Any], timeout: float) -> bool:
    """Poll ``pred`` every millisecond until it is true (True) or ``timeout`` s have passed (False)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.001)
    return False


def stop(proc: subprocess.Popen, timeout: float = 30.0) -> tuple[str | None, int | None]:
    """SIGINT ``proc`` (if it still runs) and collect it: (its stdout if piped, its exit code; None when it
    had to be killed after ``timeout`` s)."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
    try:
        out, _ = proc.communicate(timeout=timeout)
        return out, proc.returncode
    except subprocess.TimeoutExpired:
        proc.kill()
        return proc.communicate()[0], None


class NodeProcess:
    """A flow node process at ``ns``/``name`` and the client that feeds it (``pub``, message type
    ``input_type`` on ``input_topic``) and records ``flows`` [(perf_counter s, Image)] and ``diag`` (every
    diagnostics window of the node, oldest first) under ``lock``. Construction returns once the node has
    warmed up and both directions are matched (RuntimeError after 120 s)."""

    def __init__(self, ns: str, name: str, params: dict[str, str], client: str, client_ns: str | None = None,
                 input_type: type = Image, input_topic: str = "image", command: tuple[str, ...] = NODE_COMMAND,
                 log: IO[str] | None = None) -> None:
        self.name, self.flow_topic = name, f"{ns}/{name}/flow"
        self.ctx = Context()
        rclpy.init(context=self.ctx)
        self.client = Node(client, namespace=client_ns or "", context=self.ctx)
        self.pub = self.client.create_publisher(input_type, f"{ns}/{input_topic}", 10)
        self.lock = threading.Lock()
        self.flows: list[tuple[float, Image]] = []
        self.diag: list[dict[str, str]] = []
        self.client.create_subscription(Image, self.flow_topic, self._on_flow, 10)
        self.client.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 100)
        self.executor = SingleThreadedExecutor(context=self.ctx)  # as rclpy.spin in main()
        self.executor.add_node(self.client)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()
        ros_args = [a for k, v in params.items() for a in ("-p", f"{k}:={v}")]
        self.proc = subprocess.Popen(
            [*command, "--ros-args", *ros_args, "-r", f"__ns:={ns}", "-r", f"__node:={name}"],
            stdout=log or subprocess.DEVNULL, stderr=subprocess.STDOUT if log else subprocess.DEVNULL)
        if not wait(self.ready, 120.0):
            self.close()
            raise RuntimeError("the node process did not come up")

    def _on_flow(self, msg: Image) -> None:
        with self.lock:
            self.flows.append((time.perf_counter(), msg))

    def _on_diag(self, msg: DiagnosticArray) -> None:
        for st in msg.status:
            if st.name == f"{self.name}: optical flow":
                with self.lock:
                    self.diag.append({kv.key: kv.value for kv in st.values} | {"_message": st.message})

    def count(self) -> int:
        """Flows received so far."""
        with self.lock:
            return len(self.flows)

    def last(self) -> dict[str, str] | None:
        """The node's latest diagnostics window (None before the first)."""
        with self.lock:
            return self.diag[-1] if self.diag else None

    def ready(self) -> bool:
        """Warm-up done, the node subscribed to our input and our flow subscription matched."""
        last = self.last()
        return (last is not None and last["_message"] != WARMING and self.pub.get_subscription_count() > 0
                and self.client.count_publishers(self.flow_topic) > 0)

    def close(self) -> int | None:
        """Stop the node (SIGINT, killed after 30 s), then the client; the node's exit code (None if killed)."""
        _, code = stop(self.proc)
        self.executor.shutdown(timeout_sec=5.0)
        self.client.destroy_node()
        rclpy.try_shutdown(context=self.ctx)
        self.thread.join(timeout=5.0)
        return code


class Frames:
    """A smooth mono8 texture (h, w) moved by SHIFT per frame, wrapping around: ``pan`` keeps moving (a stream,
    what the stream presets predict), ``alternate`` goes back and forth between two frames."""

    def __init__(self, h: int, w: int, motion: str = "alternate") -> None:
        tex = cv2.GaussianBlur(np.random.default_rng(1).random((h, w)).astype(np.float32), (0, 0), 2.0)
        self.base = ((tex - tex.min()) / (tex.max() - tex.min()) * 255).round().astype(np.uint8)
        self.motion = motion

    def frame(self, k: int) -> np.ndarray:
        """Frame k (k >= 0)."""
        steps = k if self.motion == "pan" else k % 2
        return np.roll(self.base, (int(SHIFT[1]) * steps, int(SHIFT[0]) * steps), axis=(0, 1))

    def msg(self, k: int, stamp_ns: int) -> Image:
        """Frame k as a mono8 Image stamped ``stamp_ns``, built as the node builds its own."""
        sec, nanosec = divmod(stamp_ns, 1_000_000_000)
        return ros_image_msg(Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id="bench"),
                             array_to_image_fields(self.frame(k), "mono8"))

    def aee(self, k: int, flow: np.ndarray) -> float:
        """AEE of the flow of pair (k, k + 1) (its truth: +-SHIFT) away from the wrapped borders (8 px)."""
        sign = 1.0 if self.motion == "pan" or k % 2 == 0 else -1.0
        inner = sign * flow[8:-8, 8:-8]
        return float(np.hypot(inner[..., 0] - SHIFT[0], inner[..., 1] - SHIFT[1]).mean())


class ProcessRig(NodeProcess):
    """The node at /bench/flow_bench with ``preset``, fed by /bench/bench_client; its diagnostics every
    ``PERIOD`` s, so that a window of the closed loop holds at most one solve."""

    NAME, PERIOD = "flow_bench", 0.05

    def __init__(self, preset: str) -> None:
        super().__init__("/bench", self.NAME, {"preset": preset, "diagnostics_period": str(self.PERIOD)},
                         "bench_client", "/bench")
        self.backend = self.last()["backend"]

    def closed_loop(self, seq: Frames, n: int, timeout: float, engine: FlowEstimator) -> list[dict[str, float]]:
        """n flows, one frame in flight at a time; per flow (s): latency (publish -> flow received), the node's
        solve, in-node overhead (its handling time minus the solve) and time in rclpy's publish, and the
        engine called here on the same pair just before (same load); and the flow's AEE (px)."""
        out, stamp = [], 1
        while not wait(lambda: self.handled() >= 1, 2.0):  # best-effort input: resend the first frame
            self.pub.publish(seq.msg(0, stamp))
        for k in range(n):
            stamp += 1
            direct = engine.estimate(seq.frame(k), seq.frame(k + 1)).seconds
            before, t0 = self.count(), time.perf_counter()
            self.pub.publish(seq.msg(k + 1, stamp))
            if not wait(lambda b=before: self.count() > b, timeout):
                raise RuntimeError("no flow received (frame lost?)")
            t1, msg = self.flows[-1]
            d = self.window(k + 1, timeout)
            solve, overhead, publish = (float(d[f"{s} mean (ms)"]) / 1e3
                                        for s in ("solve time", "node overhead", "publish time"))
            out.append({"engine": direct, "latency": t1 - t0, "solve": solve, "node_overhead": overhead,
                        "node_publish": publish, "aee": seq.aee(k, image_to_array(msg))})
        return out

    def open_loop(self, seq: Frames, start_k: int, seconds: float, rate: float = 30.0) -> dict[str, float]:
        """Publish at ``rate`` Hz for ``seconds``: output rate, drops, the fraction of the time spent solving;
        the node's totals (``node_outputs``, ``node_solve_s``) include the frames still solving at the end."""
        before, d0, start, k = self.count(), self.counters(), time.perf_counter(), 0
        while time.perf_counter() - start < seconds:
            self.pub.publish(seq.msg(start_k + k, 10_000 + k))
            k += 1
            time.sleep(max(0.0, start + k / rate - time.perf_counter()))
        elapsed = time.perf_counter() - start
        busy, outputs = self.counters()["busy"] - d0["busy"], self.count() - before
        time.sleep(0.5)  # let the last counters arrive
        d1 = self.counters()
        return {"published": k, "received": d1["received"] - d0["received"], "dropped": d1["dropped"] - d0["dropped"],
                "outputs": outputs, "node_outputs": d1["published"] - d0["published"],
                "node_solve_s": d1["busy"] - d0["busy"], "seconds": elapsed, "output_rate_hz": outputs / elapsed,
                "solver_busy_fraction": busy / elapsed}

    def handled(self) -> int:
        """Frames the node has handled (published or started a pair with)."""
        last = self.last()
        return 0 if last is None else int(last["frames published"]) + int(last["resets"])

    def window(self, published: int, timeout: float) -> dict[str, str]:
        """The diagnostics window of the ``published``-th output."""
        def find() -> dict[str, str] | None:
            with self.lock:
                return next((d for d in self.diag if int(d["frames published"]) == published), None)
        if not wait(lambda: find() is not None, timeout):
            raise RuntimeError(f"no diagnostics for output {published}")
        return find()

    def counters(self) -> dict[str, float]:
        """received, dropped, published (totals) and busy (s solved since start: each window's mean solve time
        times its solves, since a loaded node's window can be longer than the timer period)."""
        busy, published = 0.0, 0
        with self.lock:
            for d in self.diag:
                solves = int(d["frames published"]) - published
                busy += float(d["solve time mean (ms)"]) / 1e3 * solves if solves else 0.0
                published += solves
            last = self.diag[-1]
        return {"received": int(last["frames received"]), "dropped": int(last["frames dropped"]),
                "published": published, "busy": busy}
