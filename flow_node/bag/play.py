"""`flow_bag play`: publish a bag's messages over DDS with their recorded timing (rclpy), for a live node.

What ``ros2 bag play`` does, for machines without rosbag2: messages are published as their recorded CDR
bytes (no re-encoding, headers unchanged), spaced by the recorded bag-time gaps divided by ``rate``.
"""

from __future__ import annotations

import importlib
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..core.errors import ConfigError
from .bagio import BagError, RecoveredReader, open_bag, read_messages


@dataclass(frozen=True)
class PlayOptions:
    """Playback settings: speed factor, loop forever (or ``loops`` times), topic renames old -> new, the
    topics to play (empty: all), and how long to wait for a subscriber on every topic before starting."""

    rate: float = 1.0
    loop: bool = False
    loops: int = 1
    remap: tuple[tuple[str, str], ...] = ()
    topics: tuple[str, ...] = ()
    wait_for_subscribers: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 < self.rate <= 1000.0:
            raise ConfigError(f"rate must be in (0, 1000], got {self.rate}")
        if self.loops < 1:
            raise ConfigError(f"loops must be >= 1, got {self.loops}")
        if not 0.0 <= self.wait_for_subscribers < 1e6:  # also NaN and inf
            raise ConfigError(f"wait-for-subscribers must be a number of seconds >= 0, got {self.wait_for_subscribers}")


def parse_remap(items: Sequence[str]) -> tuple[tuple[str, str], ...]:
    """``OLD:=NEW`` (or ``OLD:NEW``) strings -> pairs; ConfigError on anything else."""
    out = []
    for item in items:
        old, sep, new = item.partition(":=")
        if not sep:
            old, sep, new = item.partition(":")
        if not sep or not old.strip() or not new.strip():
            raise ConfigError(f"expected a remap OLD:=NEW, got {item!r}")
        out.append((old.strip(), new.strip()))
    return tuple(out)


def message_class(msgtype: str) -> Any:
    """The rclpy message class of ``pkg/msg/Name``; BagError if its Python package is not installed."""
    pkg, _, name = msgtype.split("/")
    try:
        return getattr(importlib.import_module(f"{pkg}.msg"), name)
    except (ImportError, AttributeError) as exc:
        raise BagError(f"cannot publish {msgtype}: message package {pkg} is not installed") from exc


def load_schedule(path: str | Path, topics: Sequence[str] = ()) -> tuple[dict[str, str], list[tuple[int, str, bytes]]]:
    """Read the bag: {topic: msgtype} and every message as (bag time ns, topic, CDR bytes), in order."""
    with open_bag(path) as reader:
        conns = [c for c in reader.connections if not topics or c.topic in topics]
        missing = sorted(set(topics) - {c.topic for c in conns})
        if missing:
            raise BagError(f"topic {missing[0]} is not in the bag")
        types = {c.topic: c.msgtype for c in conns}
        msgs = [(t, c.topic, bytes(raw)) for c, t, raw in read_messages(reader, conns)]
        if isinstance(reader, RecoveredReader):
            print(f"flow_bag play: warning: {reader.recovery}", file=sys.stderr)
    if not msgs:
        raise BagError(f"{path}: no messages to play")
    return types, msgs


class PlaybackInterrupted(KeyboardInterrupt):
    """Ctrl-C during playback; ``published`` says how many messages went out before it."""

    def __init__(self, published: int) -> None:
        super().__init__(f"interrupted after publishing {published} messages")
        self.published = published


def play(node: Any, path: str | Path, opts: PlayOptions,
         on_publish: Callable[[str, int, float], None] | None = None,
         stop: threading.Event | None = None) -> int:
    """Publish the bag through ``node`` (an rclpy Node) with recorded timing; returns messages published.

    ``on_publish(topic, bag_time_ns, wall_time)`` is called after each publish. The caller owns the node and
    spins it (or not) as it likes; this function only publishes and sleeps. ``stop``, once set (e.g. by a
    SIGINT handler), ends playback before the next message: the count is then exact, which a
    KeyboardInterrupt cannot promise (it may land between a publish and its count). A KeyboardInterrupt
    while playing raises :class:`PlaybackInterrupted` with the count published so far.
    """
    stop = stop if stop is not None else threading.Event()
    types, msgs = load_schedule(path, opts.topics)
    remap = dict(opts.remap)
    pubs = {topic: node.create_publisher(message_class(mt), remap.get(topic, topic), 10)
            for topic, mt in types.items()}
    _wait_for_subscribers(list(pubs.values()), opts.wait_for_subscribers, stop)
    count, loop = 0, 0
    try:
        while loop < opts.loops or opts.loop:
            start_wall, start_bag = time.monotonic(), msgs[0][0]
            for t, topic, raw in msgs:
                delay = start_wall + (t - start_bag) / 1e9 / opts.rate - time.monotonic()
                if (delay > 0 and stop.wait(delay)) or stop.is_set():
                    return count
                pubs[topic].publish(raw)
                count += 1
                if on_publish is not None:
                    on_publish(topic, t, time.monotonic())
            loop += 1
    except KeyboardInterrupt:
        raise PlaybackInterrupted(count) from None
    _wait_for_acks(list(pubs.values()))
    return count


# After a publisher sees its subscriber, how long to let the subscriber see the publisher too: discovery
# is matched on each side separately, and a volatile reader drops what arrives before its own match.
DISCOVERY_SETTLE_S = 1.0


def _wait_for_subscribers(pubs: list[Any], seconds: float, stop: threading.Event) -> None:
    """Wait until every publisher has a subscriber (at most ``seconds``), then DISCOVERY_SETTLE_S more;
    returns early once ``stop`` is set."""
    deadline = time.monotonic() + seconds
    while seconds > 0 and time.monotonic() < deadline:
        if all(p.get_subscription_count() > 0 for p in pubs):
            stop.wait(DISCOVERY_SETTLE_S)
            return
        if stop.wait(0.05):
            return


ACK_TIMEOUT_S = 2.0  # after the last message, how long to wait for reliable subscribers to acknowledge it


def _wait_for_acks(pubs: list[Any]) -> None:
    """Let every reliable subscriber acknowledge what was published (a process that exits right after its
    last publish could otherwise take an unacknowledged sample with it), ACK_TIMEOUT_S at most."""
    from rclpy.duration import Duration

    for pub in pubs:
        pub.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT_S))


def run_play(path: str | Path, opts: PlayOptions, stop: threading.Event | None = None) -> int:
    """Stand-alone playback: own rclpy context and node. Returns messages published; Ctrl-C raises
    :class:`PlaybackInterrupted` (with the count) after a clean shutdown.

    rclpy is initialised with no command-line arguments: flow_bag's own (``--topic-remap OLD:=NEW``) are not
    ROS arguments, and rcl would read ``OLD:=NEW`` as a deprecated remapping rule and warn about it. Nor
    does it install rclpy's signal handlers: those shut the context down on SIGINT without raising, and the
    next publish would fail; Python's own handler raises KeyboardInterrupt where playback is.
    """
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("flow_bag_play")
    try:
        return play(node, path, opts, stop=stop)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
