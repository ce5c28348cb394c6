"""flow_bag play over real DDS: recorded bytes and headers, recorded timing scaled by --rate, remap, loops."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore
from sensor_msgs.msg import CompressedImage, Image

from flow_node.bag.play import PlayOptions, parse_remap, play
from flow_node.core.errors import ConfigError

pytestmark = pytest.mark.ros  # rclpy over DDS: a node or a publisher in this process, or a node process

BAGS = Path(__file__).resolve().parent.parent / "bags"
TS = get_typestore(Stores.ROS2_JAZZY)


def fields(msg) -> tuple:
    """Every field of an Image/CompressedImage (rclpy or rosbags), data as bytes. (Comparing re-serialised
    CDR would be flaky: the serializer does not zero alignment padding.)"""
    h = msg.header
    rest = tuple(getattr(msg, f) for f in ("height", "width", "encoding", "is_bigendian", "step", "format")
                 if hasattr(msg, f))
    return (h.stamp.sec, h.stamp.nanosec, h.frame_id) + rest + (bytes(msg.data),)


def recorded(name: str, topic: str) -> list[tuple]:
    with Reader(BAGS / name) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        return [fields(TS.deserialize_cdr(raw, c.msgtype)) for c, _, raw in reader.messages(connections=conns)]


class Listener:
    """A subscriber in its own context, spun by a thread; records (arrival time, message)."""

    def __init__(self, topic: str, msg_type: type) -> None:
        self.ctx = Context()
        rclpy.init(context=self.ctx)
        self.node = rclpy.create_node("play_listener", context=self.ctx)
        self.got: list[tuple[float, object]] = []
        self.node.create_subscription(msg_type, topic, lambda m: self.got.append((time.monotonic(), m)), 50)
        self.executor = SingleThreadedExecutor(context=self.ctx)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def wait(self, n: int, timeout: float = 20.0) -> None:
        end = time.monotonic() + timeout
        while len(self.got) < n and time.monotonic() < end:
            time.sleep(0.02)
        stamps = [m.header.stamp.nanosec // 1_000_000 for _, m in self.got]
        assert len(self.got) >= n, f"received {len(self.got)} of {n} messages (ms of their stamps: {stamps})"

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.ctx)
        self.thread.join(timeout=5)


@pytest.mark.slow  # plays the bag in real time
def test_cli_play_publishes_recorded_bytes_with_recorded_timing():
    """10 fps bag at --rate 2: 50 ms apart; headers and data identical to the recording; remapped topic."""
    listener = Listener("/play_test/image", Image)
    cmd = [sys.executable, "-m", "flow_node.bag", "play", str(BAGS / "rotation"), "--rate", "2",
           "--topic-remap", "/camera/image_raw:=/play_test/image", "--topics", "/camera/image_raw",
           "--wait-for-subscribers", "15"]
    try:
        proc = subprocess.run(cmd, env=os.environ.copy(), capture_output=True, text=True, timeout=60)
        assert proc.returncode == 0 and proc.stdout == "flow_bag play: published 6 messages\n", proc.stderr
        listener.wait(6)
    finally:
        listener.close()
    assert [fields(m) for _, m in listener.got] == recorded("rotation", "/camera/image_raw")
    gaps = [b[0] - a[0] for a, b in zip(listener.got, listener.got[1:], strict=False)]
    assert 0.2 < listener.got[-1][0] - listener.got[0][0] < 0.6  # 5 gaps of 50 ms
    assert min(gaps) > 0.02


def test_in_process_play_loops_and_remaps_compressed():
    listener = Listener("/looped/compressed", CompressedImage)
    ctx = Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node("player", context=ctx)
    try:
        opts = PlayOptions(rate=10.0, loops=2, remap=parse_remap(["/camera/image_raw/compressed:/looped/compressed"]),
                           topics=("/camera/image_raw/compressed",), wait_for_subscribers=15.0)
        assert play(node, BAGS / "translation", opts) == 12
        listener.wait(12)
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)
        listener.close()
    raw = recorded("translation", "/camera/image_raw/compressed")
    assert [fields(m) for _, m in listener.got] == raw + raw
    assert listener.got[0][1].format == "png"


def test_play_errors():
    with pytest.raises(ConfigError):
        parse_remap(["no-separator"])
    with pytest.raises(ConfigError):
        PlayOptions(rate=0.0)
    proc = subprocess.run([sys.executable, "-m", "flow_node.bag", "play", str(BAGS / "zoom"), "--topics", "/x"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1 and proc.stderr.strip() == "flow_bag play: error: topic /x is not in the bag"


def test_cli_play_ctrl_c_reports_what_it_published_and_exits_0():
    """Ctrl-C ends a looping playback normally (exit 0, like ros2 bag play and the node) and says the real count,
    at least what a subscriber received; no rcl warning about flow_bag's own OLD:=NEW argument read as a
    deprecated remapping rule."""
    listener = Listener("/play_int/image", Image)
    cmd = [sys.executable, "-m", "flow_node.bag", "play", str(BAGS / "rotation"), "--loop", "--rate", "5",
           "--topic-remap", "/camera/image_raw:=/play_int/image", "--topics", "/camera/image_raw",
           "--wait-for-subscribers", "15"]
    proc = subprocess.Popen(cmd, env=os.environ.copy(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        listener.wait(20, timeout=30.0)  # more than three loops of the 6-frame bag
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=20)
        received = len(listener.got)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        listener.close()
    assert proc.returncode == 0, err
    match = re.fullmatch(r"flow_bag play: stopped by Ctrl-C after publishing (\d+) messages\n", out)
    assert match, (out, err)
    assert int(match.group(1)) >= received >= 20
    assert err == ""  # in particular no rcl deprecation warning


def test_play_publishes_with_the_shipped_dds_profile(monkeypatch: pytest.MonkeyPatch) -> None:
    """flow_bag play publishes frames as a camera driver does, so it applies the node's Fast DDS profile choice
    (middleware.use_shipped_dds_profile: large frames whole through shared memory) before rclpy starts."""
    from flow_node import middleware
    from flow_node.bag import cli

    class Applied(Exception):
        pass

    def applied() -> None:
        raise Applied

    monkeypatch.setattr(middleware, "use_shipped_dds_profile", applied)
    with pytest.raises(Applied):
        cli.main(["play", str(BAGS / "translation")])
