"""A hostile-input campaign against the live node over real DDS (issue 15; `make fuzz`): what it sends and what it
reports: docs/node.md, "Input encodings"; the results: BENCHMARKS.md, "Hostile input against the live node".

    .venv/bin/python -m bench.fuzz_node [--messages 300] [--seed 15] [--out bench/results/node/fuzz_node.json]
"""

from __future__ import annotations

import argparse
import array
import os
import struct
import sys
import tempfile
import time
import zlib
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from sensor_msgs.msg import CompressedImage, Image
from std_srvs.srv import Trigger

from bench.common import run_record, write_json
from bench.node_rig import NodeProcess, wait

NS, NAME = "/fuzz", "flow_node"
H, W = 60, 80
OUT = Path(__file__).resolve().parent / "results" / "node" / "fuzz_node.json"


def texture(seed: int, h: int = H, w: int = W) -> np.ndarray:
    """A smooth random mono8 texture (a pair is it and its shift by one pixel)."""
    rng = np.random.default_rng(seed)
    small = rng.random((h // 6 + 2, w // 6 + 2)).astype(np.float32)
    return (cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC).clip(0, 1) * 255).astype(np.uint8)


def raw(encoding: str, width: int, height: int, step: int, data: bytes, big: int = 0) -> Image:
    msg = Image(height=height, width=width, encoding=encoding, is_bigendian=big, step=step)
    msg.data = array.array("B", data)
    return msg


def png(img: np.ndarray, claim: tuple[int, int] | None = None) -> bytes:
    b = bytearray(cv2.imencode(".png", img)[1].tobytes())
    if claim:
        b[16:24] = struct.pack(">II", *claim)
        b[29:33] = struct.pack(">I", zlib.crc32(bytes(b[12:29])))
    return bytes(b)


def hostile_raw(rng: np.random.Generator) -> tuple[str, Image]:
    """One broken (or merely unusual) Image message and its kind."""
    tex = texture(int(rng.integers(1000)))
    f, data = (tex / 255.0).astype(np.float32), tex.tobytes()

    def floats(value: float) -> Image:
        f[rng.integers(H, size=20), rng.integers(W, size=20)] = value
        return raw("32FC1", W, H, W * 4, f.tobytes())
    make = {"step_small": lambda: raw("mono8", W, H, W - 1, data[: (W - 1) * H]),
            "step_huge": lambda: raw("mono8", W, H, 2**31, data),
            "short": lambda: raw("mono8", W, H, W, data[: len(data) // 2]),
            "long": lambda: raw("mono8", W, H, W, data + b"\0" * 77),
            "zero": lambda: raw("mono8", 0, H, 0, b""),
            "huge_dims": lambda: raw("mono8", 100000, 100000, 100000, b"\0" * 64),
            "encoding": lambda: raw(str(rng.choice(["nv21", "32FC3", "16SC1", "MONO8", "bayer_xyz8"])), W, H, W, data),
            "garbage_enc": lambda: raw(bytes(rng.integers(33, 127, 12, dtype=np.uint8)).decode(), W, H, W, data),
            "nan": lambda: floats(np.nan), "inf": lambda: floats(np.inf), "huge_float": lambda: floats(1e30),
            "max_float": lambda: floats(3.4e38),
            "big_endian16": lambda: raw("mono16", W, H, W * 2, (tex.astype(">u2") * 257).tobytes(), big=1),
            "rgb_size": lambda: raw("rgb8", 64, 48, 64 * 3,
                                    np.dstack([texture(int(rng.integers(1000)), 48, 64)] * 3).tobytes()),
            "other_size": lambda: raw("mono8", 40, 30, 40, texture(3, 30, 40).tobytes()),
            "float_ok": lambda: raw("32FC1", W, H, W * 4, f.tobytes())}
    kind = str(rng.choice(list(make)))
    return kind, make[kind]()


def hostile_compressed(rng: np.random.Generator) -> tuple[str, CompressedImage]:
    """One broken (or merely unusual) CompressedImage and its kind."""
    tex = texture(int(rng.integers(1000)))

    def flipped() -> bytes:
        b = bytearray(png(tex))
        for k in rng.integers(8, len(b), 5):
            b[k] ^= int(rng.integers(1, 256))
        return bytes(b)

    def claim_jpeg() -> bytes:
        b = bytearray(cv2.imencode(".jpg", tex)[1].tobytes())
        sof = b.index(b"\xff\xc0")
        b[sof + 5:sof + 9] = struct.pack(">HH", 60000, 60000)
        return bytes(b)
    make = {"truncated": lambda: (png(tex)[: int(rng.integers(8, 400))], "png"), "flipped": lambda: (flipped(), "png"),
            "claim_png": lambda: (png(tex, (100000, 100000)), "png"), "claim_jpeg": lambda: (claim_jpeg(), "jpeg"),
            "garbage": lambda: (bytes(rng.integers(0, 256, int(rng.integers(1, 500)), dtype=np.uint8)), "png"),
            "empty": lambda: (b"", "png"), "depth": lambda: (png(tex.astype(np.uint16)), "16UC1; compressedDepth png"),
            "other_size": lambda: (png(texture(5, 30, 40)), "png"),
            "jpeg_ok": lambda: (cv2.imencode(".jpg", tex)[1].tobytes(), "jpeg")}
    kind = str(rng.choice(list(make)))
    data, fmt = make[kind]()
    msg = CompressedImage(format=fmt)
    msg.data = array.array("B", data)
    return kind, msg


PARAMS = [("alpha", -1.0), ("alpha", 20.0), ("model", "xx"), ("model", "l1_tv_l2"), ("model", "l1_tv"),
          ("iterations", 0), ("iterations", 10), ("input_scale", 0.5), ("input_scale", 1.0), ("input_scale", 7.0),
          ("color_max_flow", float("inf")), ("color_max_flow", float("nan")), ("color_max_flow", 5.0),
          ("preset", "nope"), ("preset", "realtime"), ("levels", -3), ("scale_factor", 2.0), ("warps", 2),
          ("backend", "gpu"), ("tv_norm", "anisotropic"), ("gradient_scheme", "bogus")]


def rss_kb(pid: int) -> int:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except OSError:
        pass
    return 0


class Campaign(NodeProcess):
    """One node process (``realtime`` on numpy, raw or compressed input) and the fuzzing client, with services
    to set parameters and reset; the node's output goes to ``log``."""

    def __init__(self, compressed: bool, log: Path) -> None:
        self.compressed = compressed
        self.log = log.open("w")
        params = {"preset": "realtime", "finest_level": "0", "backend": "numpy", "diagnostics_period": "0.2",
                  "use_compressed": str(compressed).lower()}
        super().__init__(NS, NAME, params, "fuzzer", input_type=CompressedImage if compressed else Image,
                         input_topic="image/compressed" if compressed else "image", log=self.log)
        self.set_cli = self.client.create_client(SetParameters, f"{NS}/{NAME}/set_parameters")
        self.reset_cli = self.client.create_client(Trigger, f"{NS}/{NAME}/reset")
        self.stamp = 1_700_000_000_000_000_000
        self.sent = 0

    def send(self, msg: Image | CompressedImage, dt_ns: int = 33_000_000) -> None:
        self.stamp += dt_ns
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(self.stamp, 1_000_000_000)
        msg.header.frame_id = "fuzz"
        self.pub.publish(msg)
        self.sent += 1
        time.sleep(0.01)

    def valid(self, tex: np.ndarray) -> Image | CompressedImage:
        if self.compressed:
            msg = CompressedImage(format="png")
            msg.data = array.array("B", png(tex))
            return msg
        return raw("mono8", W, H, W, tex.tobytes())

    def recovery_gap(self, seed: int) -> float | None:
        """Send valid pairs until a flow arrives (up to 10 s); seconds it took, None for a hang."""
        start = time.monotonic()
        with self.lock:
            n = len(self.flows)
        tex = texture(seed)
        while time.monotonic() - start < 10.0:
            self.send(self.valid(tex))
            self.send(self.valid(np.roll(tex, 1, axis=1)))
            if wait(lambda: len(self.flows) > n, 1.0):
                return time.monotonic() - start
        return None

    def call(self, cli: Any, request: Any) -> Any:
        if not cli.wait_for_service(timeout_sec=5.0):
            return None
        future = cli.call_async(request)
        return future.result() if wait(future.done, 10.0) else None

    def close(self) -> int | None:
        """Stop the node and the client (NodeProcess.close), close the log; the node's exit code."""
        code = super().close()
        self.log.close()
        return code


def run_phase(compressed: bool, messages: int, seed: int) -> dict[str, Any]:
    rng = np.random.default_rng(seed + int(compressed))
    log = Path(tempfile.mkdtemp(prefix="fuzz_node_")) / "node.log"
    c = Campaign(compressed, log)
    rss = [rss_kb(c.proc.pid)]
    kinds: dict[str, int] = {}
    params = {"accepted": 0, "rejected": 0, "rejected_without_reason": 0, "no_answer": 0}
    resets = {"ok": 0, "failed": 0}
    gaps: list[float] = []
    hangs = 0
    for k in range(messages):
        kind, msg = hostile_compressed(rng) if compressed else hostile_raw(rng)
        kinds[kind] = kinds.get(kind, 0) + 1
        dt = int(rng.choice([33_000_000, 33_000_000, 0, -5_000_000_000, 3_600_000_000_000]))
        c.send(msg, dt)
        if k % 10 == 5:
            batch = [PARAMS[i] for i in rng.choice(len(PARAMS), int(rng.integers(1, 3)), replace=False)]
            req = SetParameters.Request(parameters=[Parameter(n, value=v).to_parameter_msg() for n, v in batch])
            res = c.call(c.set_cli, req)
            if res is None:
                params["no_answer"] += 1
            for r in res.results if res is not None else []:
                params["accepted" if r.successful else "rejected"] += 1
                params["rejected_without_reason"] += int(not r.successful and not r.reason)
        if k % 15 == 7:
            res = c.call(c.reset_cli, Trigger.Request())
            resets["ok" if res is not None and res.success else "failed"] += 1
        if k % 20 == 19:
            gap = c.recovery_gap(seed + k)
            hangs += gap is None
            gaps.append(gap if gap is not None else float("inf"))
            rss.append(rss_kb(c.proc.pid))
    time.sleep(1.0)  # the last diagnostics window
    alive = c.proc.poll() is None
    rss.append(rss_kb(c.proc.pid))
    with c.lock:
        flows = [msg for _, msg in c.flows]
    diag = c.last() or {}
    sent = c.sent
    code = c.close()
    log_text = log.read_text(errors="replace")
    nonfinite = sum(not np.isfinite(np.frombuffer(bytes(f.data), np.float32)).all() for f in flows)
    return {
        "input": "CompressedImage" if compressed else "Image",
        "hostile_messages": messages, "messages_sent": sent, "kinds": dict(sorted(kinds.items())),
        "node": {key: int(diag.get(f"frames {key}", diag.get(key, -1))) for key in
                 ("received", "rejected", "published", "dropped")}
        | {"resets": int(diag.get("resets", -1)), "engine_errors": int(diag.get("engine errors", -1)),
           "last_rejection": diag.get("last rejection", "")},
        "flows_received": len(flows), "flows_with_nan_or_inf": int(nonfinite),
        "set_parameters": params, "reset_calls": resets,
        "crashes": int(not alive) + log_text.count("Traceback"), "hangs": hangs,
        "recovery_gap_s": {"max": max(gaps) if gaps else None, "median": float(np.median(gaps)) if gaps else None},
        "rss_mb": {"start": rss[0] / 1024, "max": max(rss) / 1024, "end": rss[-1] / 1024},
        "sigint_exit_code": code,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--messages", type=int, default=300, help="hostile messages per input kind")
    ap.add_argument("--seed", type=int, default=15)
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    results = [run_phase(compressed, args.messages, args.seed) for compressed in (False, True)]
    write_json(args.out, {**run_record("bench.fuzz_node", argv), "seed": args.seed, "phases": results})
    for r in results:
        n = r["node"]
        print(f"{r['input']}: {r['hostile_messages']} hostile + valid = {r['messages_sent']} sent; node received "
              f"{n['received']}, rejected {n['rejected']}, published {n['published']}, resets {n['resets']}, "
              f"engine errors {n['engine_errors']}; flows with NaN/inf {r['flows_with_nan_or_inf']}; "
              f"crashes {r['crashes']}, hangs {r['hangs']}, max gap {r['recovery_gap_s']['max']:.2f} s; "
              f"RSS {r['rss_mb']['start']:.0f}/{r['rss_mb']['max']:.0f}/{r['rss_mb']['end']:.0f} MB; "
              f"SIGINT exit {r['sigint_exit_code']}")
    bad = any(r["crashes"] or r["hangs"] or r["flows_with_nan_or_inf"] or r["node"]["engine_errors"]
              or r["set_parameters"]["rejected_without_reason"] or r["sigint_exit_code"] != 0 for r in results)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
