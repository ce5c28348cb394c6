"""`make demo`: the whole product on one screen.

Starts the flow node (``python -m flow_node.ros.node``, the ``balanced`` preset: the bag's frames are 128x96,
too small for ``realtime``'s half-resolution solve; its ``image`` remapped to the bag's camera topic) on an
isolated DDS domain (localhost discovery, a random domain id), plays the bundled bag into it with ``flow_bag
play``'s publisher, collects ``/flow_node/flow`` and ``/diagnostics``, and prints a per-frame table (AEE
against the bag's ground truth, latency from publish to flow received) and a summary, side by side with
``flow_bag eval`` of the same bag (same pipeline, offline). Writes colour PNGs to ``demo_out/``. Stops the
node and exits 0 when every frame pair came back; nothing is left running.
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from .core.config import PRESETS, FlowConfig
from .core.errors import FlowError
from .core.flowio import flow_to_color
from .core.metrics import aee, angular_error

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_BAG = ROOT / "bags" / "objects"
NODE_NAME = "flow_node"
DIAG_NAME = f"{NODE_NAME}: optical flow"


@dataclass(frozen=True)
class DemoOptions:
    """Bag, output folder, node preset and backend, playback rate, and how long to wait for the node to
    be ready (numba compiles its kernels on a cold cache) and for the last flow."""

    bag: Path = DEFAULT_BAG
    out_dir: Path = Path("demo_out")
    preset: str = "balanced"
    backend: str = "numpy"
    rate: float = 0.5
    ready_timeout: float = 120.0
    drain_timeout: float = 3.0

    def config(self) -> FlowConfig:
        """The engine config the node runs with (its parameters: preset, then backend)."""
        return FlowConfig.preset(self.preset).replace(backend=self.backend)


@dataclass
class FrameRow:
    """One frame pair as seen live, with the offline eval's numbers for the same pair."""

    index: int
    stamp_ns: int
    flow: np.ndarray | None = None
    latency: float | None = None
    aee: float | None = None
    ae: float | None = None
    eval_aee: float | None = None
    max_diff: float | None = None
    note: str = ""


@dataclass
class DemoResult:
    rows: list[FrameRow]
    diagnostics: dict[str, str] = field(default_factory=dict)
    diag_level: int | None = None
    diag_message: str = ""
    node_exit: int | None = None

    @property
    def received(self) -> int:
        return sum(r.flow is not None for r in self.rows)


def isolate_dds() -> int:
    """Localhost-only discovery and a random domain id (1..100) for this process and its children."""
    domain = random.SystemRandom().randint(1, 100)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    return domain


def load_bag(bag: Path) -> tuple[str, list[tuple[int, int]], dict[int, np.ndarray]]:
    """The bag's image topic, its (bag time, header stamp) per image, and ground truth by stamp."""
    from .bag.bagio import IMAGE, IMAGE_TYPES, deserialize, find_connections, open_bag, read_messages, stamp_ns
    from .bag.evaluate import DEFAULT_GT_TOPIC
    from .pipeline.codec import image_to_array

    with open_bag(bag) as reader:
        gt_conns = find_connections(reader, DEFAULT_GT_TOPIC, (IMAGE,), "gt", required=False)
        images = find_connections(reader, None, IMAGE_TYPES, "image", exclude=(DEFAULT_GT_TOPIC,))
        times, gts = [], {}
        for conn, t, raw in read_messages(reader, images + gt_conns):
            msg = deserialize(raw, conn.msgtype)
            if conn in gt_conns:
                gts[stamp_ns(msg)] = image_to_array(msg)
            else:
                times.append((t, stamp_ns(msg)))
    return images[0].topic, times, gts


def start_node(opts: DemoOptions, topic: str, log: Path) -> subprocess.Popen:
    """The node as a child process, remapped to ``topic``, output to ``log``."""
    cmd = [sys.executable, "-m", "flow_node.ros.node", "--ros-args", "-r", f"image:={topic}",
           "-p", f"preset:={opts.preset}", "-p", f"backend:={opts.backend}", "-p", "diagnostics_period:=0.5"]
    with open(log, "w") as fh:
        return subprocess.Popen(cmd, stdout=fh, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)


def stop_node(proc: subprocess.Popen) -> int:
    """SIGINT (the node shuts down cleanly), then SIGKILL if it does not exit; returns its exit code."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            return proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
    return proc.wait()


class Collector:
    """The demo's rclpy node: subscribes to the node's flow and /diagnostics, records arrival times."""

    def __init__(self, ctx: Any) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.node import Node
        from sensor_msgs.msg import Image

        self.node = Node("flow_demo", context=ctx)
        self.flows: dict[int, tuple[np.ndarray, float]] = {}
        self.diag: Any = None  # the node's latest status
        self.busy_diag: Any = None  # its latest status of a period in which it solved frames
        self.lock = threading.Lock()
        self.node.create_subscription(Image, f"/{NODE_NAME}/flow", self._on_flow, 10)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 10)

    def _on_flow(self, msg: Any) -> None:
        from .pipeline.codec import image_to_array

        now = time.monotonic()
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        with self.lock:
            self.flows[stamp] = (image_to_array(msg).copy(), now)

    def _on_diag(self, msg: Any) -> None:
        for st in msg.status:
            if st.name == DIAG_NAME:
                with self.lock:
                    self.diag = st
                    if any(kv.key == "solve time mean (ms)" and kv.value != "n/a" for kv in st.values):
                        self.busy_diag = st

    def ready(self) -> bool:
        """The node has finished its warm-up (its diagnostics say so)."""
        with self.lock:
            return self.diag is not None and self.diag.message != "warming up the engine"


def _wait(pred: Any, timeout: float, proc: subprocess.Popen, what: str) -> None:
    end = time.monotonic() + timeout
    while not pred():
        if proc.poll() is not None:
            raise FlowError(f"the node exited with code {proc.returncode} while {what}; see its log")
        if time.monotonic() > end:
            raise FlowError(f"timed out after {timeout:.0f} s {what}")
        time.sleep(0.05)


def run_demo(opts: DemoOptions) -> DemoResult:
    """Start the node, play the bag into it, collect; also evaluate the bag offline. Never leaves the node
    running. Uses the DDS settings of the environment (``main`` isolates them)."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    from .bag.evaluate import evaluate
    from .bag.play import PlayOptions, play
    from .bag.results import EvalOptions

    topic, times, gts = load_bag(opts.bag)
    offline = evaluate(opts.bag, None, [opts.config()], EvalOptions(png_frames="all", progress=False))
    opts.out_dir.mkdir(parents=True, exist_ok=True)
    proc = start_node(opts, topic, opts.out_dir / "node.log")
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    collector = Collector(ctx)
    executor.add_node(collector.node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    sent: dict[int, float] = {}
    result = DemoResult([])
    try:
        _wait(collector.ready, opts.ready_timeout, proc, "waiting for the node to warm up")
        stamps = dict(times)
        play(collector.node, opts.bag, PlayOptions(rate=opts.rate, topics=(topic,), wait_for_subscribers=10.0),
             on_publish=lambda _t, bag_t, wall: sent.__setitem__(stamps[bag_t], wall))
        pairs = [s for _, s in times[1:]]
        try:
            _wait(lambda: all(s in collector.flows for s in pairs), opts.drain_timeout, proc,
                  "waiting for the last flow")
        except FlowError:
            pass  # reported as missing rows
        time.sleep(0.6)  # one more diagnostics period
    finally:
        result.node_exit = stop_node(proc)
        executor.shutdown()
        collector.node.destroy_node()
        rclpy.try_shutdown(context=ctx)
        spinner.join(timeout=5)
    result.rows = _rows(times, gts, collector.flows, sent, offline)
    if collector.diag is not None:
        busy = collector.busy_diag or collector.diag
        result.diagnostics = {kv.key: kv.value for kv in busy.values}
        result.diagnostics.update({kv.key: kv.value for kv in collector.diag.values
                                   if kv.key.startswith("frames") or kv.key == "resets"})
        level = collector.diag.level  # a ROS byte: bytes of length 1 in rclpy
        result.diag_level = level[0] if isinstance(level, bytes) else int(level)
        result.diag_message = collector.diag.message
    return result


def _rows(times: list[tuple[int, int]], gts: dict[int, np.ndarray], flows: dict[int, tuple[np.ndarray, float]],
          sent: dict[int, float], offline: Any) -> list[FrameRow]:
    """Per frame pair: live flow, latency, AEE/AE vs GT, offline AEE and the largest live-offline difference."""
    drawn = {d.stamp_ns: next(iter(d.flows.values())) for d in offline.drawn if d.flows}
    records = {r.stamp_ns: r for r in offline.runs[0].records}
    rows: list[FrameRow] = []
    for k, (_, stamp) in enumerate(times[1:], start=1):
        row = FrameRow(k, stamp)
        rec = records.get(stamp)
        row.eval_aee = None if rec is None else rec.aee
        if stamp in flows:
            row.flow, arrived = flows[stamp]
            row.latency = arrived - sent[stamp] if stamp in sent else None
            if k > 1 and rows[-1].flow is None:
                # the node dropped the previous frame (stale): this flow spans two frame gaps
                row.note = "after a dropped frame: not compared"
            else:
                if stamp in gts:
                    row.aee, row.ae = aee(row.flow, gts[stamp]), angular_error(row.flow, gts[stamp])
                if stamp in drawn:
                    row.max_diff = float(np.abs(row.flow - drawn[stamp]).max())
        rows.append(row)
    return rows


def _f(x: float | None, fmt: str) -> str:
    """``x`` formatted, or '-' padded to the same width."""
    return format(x, fmt) if x is not None else "-".rjust(int(fmt.split(".")[0] or 0))


def report_lines(result: DemoResult, opts: DemoOptions) -> list[str]:
    """The per-frame table and the summary."""
    lines = [f"{'frame':>5} {'AEE px':>8} {'AE deg':>7} {'latency ms':>10} {'eval AEE':>9} {'|live-eval|':>11}"]
    for r in result.rows:
        lat = None if r.latency is None else 1000 * r.latency
        lines.append(f"{r.index:>5} {_f(r.aee, '8.3f')} {_f(r.ae, '7.2f')} {_f(lat, '10.1f')} "
                     f"{_f(r.eval_aee, '9.3f')} {_f(r.max_diff, '11.2e')}  {r.note}" if r.flow is not None else
                     f"{r.index:>5} {'-':>8} {'-':>7} {'-':>10} {_f(r.eval_aee, '9.3f')} {'-':>11}  "
                     "no flow (the node dropped this frame: it was still solving the previous one)")
    got = [r for r in result.rows if r.flow is not None]
    aees = [r.aee for r in got if r.aee is not None]
    lats = [1000 * r.latency for r in got if r.latency is not None]
    d = result.diagnostics
    lines += ["", f"summary: {len(got)}/{len(result.rows)} frame pairs received over DDS; "
              f"mean AEE {_f(float(np.mean(aees)) if aees else None, '.3f')} px; "
              f"latency median {_f(float(np.median(lats)) if lats else None, '.1f')} ms, "
              f"max {_f(max(lats) if lats else None, '.1f')} ms",
              f"node: model {d.get('model', '?')}, backend {d.get('backend', '?')}, preset {opts.preset}; "
              f"solve time mean {d.get('solve time mean (ms)', '?')} ms (while busy); frames received "
              f"{d.get('frames received', '?')}, published {d.get('frames published', '?')}, dropped "
              f"{d.get('frames dropped', '?')}; diagnostics: {result.diag_message or 'none received'}",
              f"offline flow_bag eval of the same bag (same pipeline): largest difference to the live flow "
              f"{_f(max((r.max_diff for r in got if r.max_diff is not None), default=None), '.2e')} px"]
    return lines


def write_pngs(result: DemoResult, out_dir: Path, max_flow: float = 4.0) -> list[Path]:
    """Colour-coded flow (Middlebury wheel, fixed scale) of every received pair."""
    paths = []
    for r in result.rows:
        if r.flow is not None:
            p = out_dir / f"flow_{r.index:04d}.png"
            big = cv2.resize(flow_to_color(r.flow, max_flow, bgr=True), None, fx=3, fy=3,
                             interpolation=cv2.INTER_NEAREST)
            cv2.imwrite(str(p), big)
            paths.append(p)
    return paths


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m flow_node.demo", description=__doc__.splitlines()[0])
    p.add_argument("--bag", type=Path, default=DEFAULT_BAG, help="bag with ground truth to play")
    p.add_argument("--out", type=Path, default=Path("demo_out"), help="folder for PNGs and the node log")
    p.add_argument("--preset", choices=tuple(PRESETS), default="balanced", help="node preset")
    p.add_argument("--backend", choices=("numpy", "numba", "auto"), default="numpy",
                   help="solver backend of the node (numpy needs no JIT compile; on 128x96 frames it is as fast)")
    p.add_argument("--rate", type=float, default=0.5, help="playback speed factor")
    args = p.parse_args(argv)
    domain = isolate_dds()
    opts = DemoOptions(args.bag, args.out, args.preset, args.backend, args.rate)
    print(f"flow_node demo: node on ROS_DOMAIN_ID={domain} (localhost only), bag {opts.bag}, "
          f"preset {opts.preset}, backend {opts.backend}, playback x{opts.rate}")
    start = time.monotonic()
    try:
        result = run_demo(opts)
    except FlowError as exc:
        print(f"demo: error: {exc}", file=sys.stderr)
        return 1
    print("\n".join(report_lines(result, opts)))
    pngs = write_pngs(result, opts.out_dir)
    print(f"wrote {len(pngs)} colour PNGs and node.log to {opts.out_dir}/ ({time.monotonic() - start:.1f} s in all)")
    if 2 * result.received < len(result.rows):
        print(f"demo: error: only {result.received} of {len(result.rows)} flows came back", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
