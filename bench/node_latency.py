"""Node latency, throughput and overhead beyond the engine's solve time, over real DDS.

    .venv/bin/python -m bench.node_latency [--frames N] [--out bench/results/node/node_latency.json]

The node runs as its own process (``python -m flow_node.ros.node``, as ``ros2 run`` does) and reports its
per-frame solve time and in-node overhead on /diagnostics (every 50 ms, so each window holds one solve). For
each size (320x240, 640x480) and preset (realtime, quality), in one run:

* engine: ``FlowEstimator.estimate`` called here on the same pair right before each node frame (the peer
  the latency ratio refers to);
* latency: closed loop, publish a frame -> its ~/flow message received, next frame only after that, so
  nothing is dropped; in-node overhead = node handling time (decode, grey, magnitude, serialise, publish)
  minus the engine's solve time, measured by the node itself per frame, and the part of it spent inside
  rclpy's ``publish`` (C conversion, serialisation, Fast DDS send), also measured by the node;
* throughput: open loop, frames published at 30 Hz for four solve times (at least 3 s): output rate, and
  the fraction of the wall time the worker spent inside the engine (1.0 = no overhead at all).

Backend ``auto`` (numba if importable), like a default node. Frames: smooth random texture, shifted by
(2, 1) px between frames. The machine is shared: report medians and ratios, not absolute speed.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from builtin_interfaces.msg import Time
from sensor_msgs.msg import Image
from std_msgs.msg import Header

from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig
from flow_node.pipeline.codec import array_to_image_fields, image_to_array
from flow_node.ros.messages import image_msg as ros_image_msg

from .common import run_record, write_json
from .node_rig import NODE_COMMAND, NodeProcess, wait

SIZES = ((240, 320), (480, 640))
PRESETS = ("realtime", "quality")
SHIFT = (2.0, 1.0)  # (u, v) px


class Frames:
    """The published frames: a smooth mono8 texture moved by SHIFT per frame (frame k+1 (x + SHIFT) = frame k
    (x), the texture wrapping around): ``pan`` keeps moving (a stream, what the stream presets predict),
    ``alternate`` goes back and forth between two frames (each pair's motion the reverse of the last)."""

    def __init__(self, h: int, w: int, motion: str = "alternate") -> None:
        rng = np.random.default_rng(1)
        tex = cv2.GaussianBlur(rng.random((h, w)).astype(np.float32), (0, 0), 2.0)
        tex = (tex - tex.min()) / (tex.max() - tex.min())
        self.base, self.motion = (tex * 255).round().astype(np.uint8), motion

    def frame(self, k: int) -> np.ndarray:
        """Frame k (k >= 0)."""
        steps = k if self.motion == "pan" else k % 2
        return np.roll(self.base, (int(SHIFT[1]) * steps, int(SHIFT[0]) * steps), axis=(0, 1))

    def sign(self, k: int) -> float:
        """The true flow of the pair (k, k + 1) is sign(k) x SHIFT."""
        return 1.0 if self.motion == "pan" or k % 2 == 0 else -1.0


def image_msg(arr: np.ndarray, stamp_ns: int) -> Image:
    """A mono8 Image of ``arr`` stamped ``stamp_ns``, built as the node builds its own."""
    sec, nanosec = divmod(stamp_ns, 1_000_000_000)
    return ros_image_msg(Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id="bench"),
                         array_to_image_fields(arr, "mono8"))


def interior_aee(flow: np.ndarray) -> float:
    """AEE against SHIFT away from the wrapped borders (8 px)."""
    inner = flow[8:-8, 8:-8]
    return float(np.hypot(inner[..., 0] - SHIFT[0], inner[..., 1] - SHIFT[1]).mean())


class ProcessRig(NodeProcess):
    """The node as its own process at /bench/flow_bench with ``preset``, fed by the client /bench/bench_client;
    per-frame times from its /diagnostics, published every ``PERIOD`` s, so each window holds at most one
    solve in the closed loop."""

    NAME = "flow_bench"
    PERIOD = 0.05

    def __init__(self, preset: str, command: tuple[str, ...] = NODE_COMMAND) -> None:
        """``command`` starts the node and takes ROS arguments after it (default: the node's own main())."""
        super().__init__("/bench", self.NAME, {"preset": preset, "diagnostics_period": str(self.PERIOD)},
                         "bench_client", "/bench", command=command)
        self.backend = self.last()["backend"]

    def closed_loop(self, seq: Frames, n: int, timeout: float, engine: FlowEstimator) -> list[dict[str, float]]:
        """n flows, one frame in flight at a time; per flow: latency, solve and in-node overhead (s), and the
        engine called directly on the same pair just before (same load conditions)."""
        out = []
        stamp = 1
        while not wait(lambda: self.handled() >= 1, 2.0):  # best-effort input: resend the first frame
            self.pub.publish(image_msg(seq.frame(0), stamp))
        for k in range(n):
            stamp += 1
            direct = engine.estimate(seq.frame(k), seq.frame(k + 1)).seconds
            before = self.count()
            t0 = time.perf_counter()
            self.pub.publish(image_msg(seq.frame(k + 1), stamp))
            if not wait(lambda b=before: self.count() > b, timeout):
                raise RuntimeError("no flow received (frame lost?)")
            t1, msg = self.flows[-1]
            solve, overhead, publish = self.frame_times(k + 1, timeout)
            sign = seq.sign(k)
            out.append({"engine": direct, "latency": t1 - t0, "solve": solve, "node_overhead": overhead,
                        "node_publish": publish, "aee": interior_aee(sign * image_to_array(msg))})
        return out

    def open_loop(self, seq: Frames, start_k: int, seconds: float, rate: float = 30.0) -> dict[str, float]:
        """Publish at ``rate`` Hz for ``seconds``; output rate, drops, fraction of the time spent solving. The
        node's totals (``node_outputs`` and their solve seconds ``node_solve_s``) include the frames still
        being solved when publishing stops."""
        before, d0 = self.count(), self.counters()
        start = time.perf_counter()
        k = 0
        while time.perf_counter() - start < seconds:
            self.pub.publish(image_msg(seq.frame(start_k + k), 10_000 + k))
            k += 1
            time.sleep(max(0.0, start + k / rate - time.perf_counter()))
        elapsed = time.perf_counter() - start
        busy = self.counters()["busy"] - d0["busy"]  # solving time within the window
        outputs = self.count() - before
        time.sleep(0.5)  # let the last counters arrive
        d1 = self.counters()
        return {"published": k, "received": d1["received"] - d0["received"],
                "dropped": d1["dropped"] - d0["dropped"], "outputs": outputs,
                "node_outputs": d1["published"] - d0["published"], "node_solve_s": d1["busy"] - d0["busy"],
                "seconds": elapsed,
                "output_rate_hz": outputs / elapsed, "solver_busy_fraction": busy / elapsed}

    def handled(self) -> int:
        """Frames the node has handled (published or started a pair with)."""
        last = self.last()
        return 0 if last is None else int(last["frames published"]) + int(last["resets"])

    def frame_times(self, published: int, timeout: float) -> tuple[float, float, float]:
        """(solve, in-node overhead, time in publish) seconds of the ``published``-th output."""

        def window() -> dict[str, str] | None:
            with self.lock:
                return next((d for d in self.diag if int(d["frames published"]) == published), None)
        if not wait(lambda: window() is not None, timeout):
            raise RuntimeError(f"no diagnostics for output {published}")
        d = window()
        return tuple(float(d[f"{k} mean (ms)"]) / 1e3 for k in ("solve time", "node overhead", "publish time"))

    def counters(self) -> dict[str, float]:
        """received, dropped, published (totals) and busy (seconds solved since start): busy sums each window's
        solve time mean times the solves in it (a window can be longer than the timer period when the node is
        loaded, so its busy % times the period would not do)."""
        busy, published = 0.0, 0
        with self.lock:
            for d in self.diag:
                solves = int(d["frames published"]) - published
                if solves:
                    busy += float(d["solve time mean (ms)"]) / 1e3 * solves
                published += solves
            last = self.diag[-1]
        return {"received": int(last["frames received"]), "dropped": int(last["frames dropped"]),
                "published": published, "busy": busy}


def run(preset: str, size: tuple[int, int], n: int, motion: str = "alternate") -> dict[str, Any]:
    seq = Frames(*size, motion)
    engine = FlowEstimator(FlowConfig.preset(preset))
    engine.warmup()
    first = engine.estimate(seq.frame(0), seq.frame(1)).seconds
    rig = ProcessRig(preset)
    try:
        loop = rig.closed_loop(seq, n, 30.0 * first + 10.0, engine)
        tput = rig.open_loop(seq, n + 1, max(3.0, 4 * statistics.median(d["solve"] for d in loop)))
        backend = rig.backend
    finally:
        rig.close()
    med = {k: statistics.median(d[k] for d in loop) for k in loop[0]}
    eng = med["engine"]
    return {
        "preset": preset, "config": FlowConfig.preset(preset).to_dict(), "width": size[1], "height": size[0],
        "frames": n, "motion": motion, "backend": backend, "node": "own process",
        "engine_solve_median_s": eng,
        "node_solve_median_s": med["solve"],
        "latency_median_s": med["latency"],
        "latency_max_s": max(d["latency"] for d in loop),
        "node_overhead_median_s": med["node_overhead"],
        "node_overhead_ratio": med["node_overhead"] / med["solve"],
        "node_publish_median_s": med["node_publish"],
        "node_publish_ratio": med["node_publish"] / med["solve"],
        "end_to_end_overhead_ratio": (med["latency"] - med["solve"]) / med["solve"],
        "latency_vs_engine_ratio": med["latency"] / eng,
        "aee_interior_px": med["aee"],
        "throughput": tput,
        "per_frame": loop,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=5, help="flows per case in the closed loop (default 5)")
    ap.add_argument("--out", default="bench/results/node/node_latency.json")
    ap.add_argument("--presets", nargs="+", default=list(PRESETS))
    ap.add_argument("--motion", choices=("alternate", "pan"), default="alternate",
                    help="frames back and forth between two (default) or a steady pan (a stream: stream presets)")
    args = ap.parse_args(argv)
    results = []
    for preset in args.presets:
        for size in SIZES:
            r = run(preset, size, args.frames, args.motion)
            results.append(r)
            tp = r["throughput"]
            print(f"{preset:9s} {r['width']}x{r['height']} {r['backend']}: "
                  f"engine {r['engine_solve_median_s']*1e3:8.1f} ms"
                  f" | latency {r['latency_median_s']*1e3:8.1f} ms (x{r['latency_vs_engine_ratio']:.3f})"
                  f" | in-node overhead {100*r['node_overhead_ratio']:5.2f} %"
                  f" (publish {100*r['node_publish_ratio']:5.2f} %)"
                  f" | end-to-end overhead {100*r['end_to_end_overhead_ratio']:5.2f} %"
                  f" | throughput {tp['output_rate_hz']:.2f} Hz (solving {tp['solver_busy_fraction']:.2f})"
                  f" | AEE {r['aee_interior_px']:.3f}", flush=True)
    write_json(Path(args.out), {"meta": run_record("bench.node_latency", argv), "results": results})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
