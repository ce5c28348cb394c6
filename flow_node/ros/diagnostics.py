"""What the node reports on /diagnostics: counters and per-window statistics, the level rules, the message.

:class:`NodeStats` is plain Python (thread-safe): the subscription and the worker record events, the
diagnostics timer takes a :meth:`NodeStats.window` snapshot once per period, which also starts the next
window. Rates and solve times are over that window; counters are totals since start.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from ..core.photometric import UNRELIABLE
from ..pipeline.stream import FlowOutput, FlowSummary, StreamTotals

OK, WARN, ERROR = DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR


@dataclass
class Totals:
    """Counters since start."""

    received: int = 0
    processed: int = 0
    published: int = 0
    dropped: int = 0
    rejected: int = 0
    resets: int = 0
    errors: int = 0
    analysed: int = 0  # pairs whose derived motion outputs were computed (some ~/motion/* subscribed)
    predicted: int = 0  # pairs the stream mode solved from the previous flow (core/temporal.py)
    stream_fallbacks: int = 0  # pairs the stream mode solved in full because the prediction failed a check


@dataclass
class Window:
    """One diagnostics period: deltas of the totals, solve/overhead/publish times (s), last values."""

    seconds: float
    totals: Totals
    received: int
    published: int
    dropped: int
    rejected: int
    errors: int
    solve_times: list[float]
    overheads: list[float]
    publish_times: list[float]
    summary: FlowSummary | None
    last_reset: str
    last_rejection: str
    last_error: str
    since_input: float | None
    unreliable: int = 0  # outputs of the period whose unexplained fraction exceeds UNRELIABLE
    unexplained: float | None = None  # of the last output
    motion_times: list[float] = field(default_factory=list)  # seconds of the derived outputs, per analysed pair
    last_stream_fallback: str = ""  # NodeStats.stream.last_fallback


@dataclass
class NodeStats:
    """Thread-safe event recorder for the node."""

    totals: Totals = field(default_factory=Totals)
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)
    _start: float = field(default_factory=time.monotonic)
    _mark: Totals = field(default_factory=Totals)
    _solve: list[float] = field(default_factory=list)
    _overhead: list[float] = field(default_factory=list)
    _publish: list[float] = field(default_factory=list)
    _motion: list[float] = field(default_factory=list)
    _unreliable: int = 0
    _last: FlowOutput | None = None
    _last_input: float | None = None
    last_reset: str = ""
    last_rejection: str = ""
    last_error: str = ""
    stream: StreamTotals = field(default_factory=StreamTotals)  # the stream mode's pairs (predicted, fallbacks)
    solve_max: float = 0.0  # longest solve since start (s)
    solve_total: float = 0.0  # seconds spent solving since start

    @property
    def last(self) -> FlowOutput | None:
        """The last published output (its colour, confidence, ... as far as they were computed), or None."""
        with self._lock:
            return self._last

    def received(self, dropped_previous: bool) -> None:
        with self._lock:
            self.totals.received += 1
            self.totals.dropped += int(dropped_previous)
            self._last_input = time.monotonic()

    def dropped(self) -> None:
        """A received frame was discarded without being handled (the node was deactivated)."""
        with self._lock:
            self.totals.dropped += 1

    def rejected(self, reason: str) -> None:
        with self._lock:
            self.totals.rejected += 1
            self.last_rejection = reason

    def error(self, reason: str) -> None:
        with self._lock:
            self.totals.errors += 1
            self.last_error = reason

    def reset(self, reason: str) -> None:
        with self._lock:
            self.totals.processed += 1
            self.totals.resets += 1
            self.last_reset = reason

    def solved(self, solve_s: float, overhead_s: float, publish_s: float, output: FlowOutput) -> None:
        """A pair was solved and published: engine seconds, node seconds beyond the engine, the part of those
        spent in rclpy's ``publish`` calls, the output (kept until the next one; its magnitude summary is
        computed only when a diagnostics window needs it)."""
        with self._lock:
            self.totals.processed += 1
            self.totals.published += 1
            self._solve.append(solve_s)
            self.solve_max = max(self.solve_max, solve_s)
            self.solve_total += solve_s
            self._overhead.append(overhead_s)
            self._publish.append(publish_s)
            self._unreliable += int(output.unexplained > UNRELIABLE)
            self._last = output
            self.stream.count(output.stats.stream if output.stats is not None else "")
            self.totals.predicted, self.totals.stream_fallbacks = self.stream.predicted, self.stream.fallbacks

    def analysed(self, seconds: float) -> None:
        """The derived motion outputs of a pair were computed (and published) in ``seconds``."""
        with self._lock:
            self.totals.analysed += 1
            self._motion.append(seconds)

    def window(self) -> Window:
        """Snapshot of the period since the last call; starts the next period. The flow summary of the last
        output is computed here, outside the lock, so the worker never waits for it."""
        with self._lock:
            now = time.monotonic()
            t, m, last = self.totals, self._mark, self._last
            w = Window(now - self._start, Totals(**vars(t)), t.received - m.received, t.published - m.published,
                       t.dropped - m.dropped, t.rejected - m.rejected, t.errors - m.errors, self._solve,
                       self._overhead, self._publish, None, self.last_reset, self.last_rejection, self.last_error,
                       None if self._last_input is None else now - self._last_input, self._unreliable,
                       None if last is None else last.unexplained, self._motion, self.stream.last_fallback)
            self._start, self._mark = now, Totals(**vars(t))
            self._solve, self._overhead, self._publish, self._motion, self._unreliable = [], [], [], [], 0
        w.summary = None if last is None else last.summary
        return w


def too_slow(w: Window) -> str | None:
    """Why the solver cannot keep up with the input of this period, or None: its mean solve time is longer
    than the mean interval between received frames (needs 3 received and 1 solved frame to judge)."""
    if w.received < 3 or not w.solve_times:
        return None
    solve = sum(w.solve_times) / len(w.solve_times)
    interval = w.seconds / w.received
    if solve <= interval:
        return None
    return (f"solver too slow for the input: {1000.0 * solve:.0f} ms per pair, a frame every "
            f"{1000.0 * interval:.0f} ms ({w.received / w.seconds:.1f} Hz); dropped {w.dropped} of {w.received} "
            "(use preset realtime or fastest, or input_scale < 1)")


def lifecycle_level(state: str, failure: str = "") -> tuple[int, str] | None:
    """Level and reason of a node that is not active (None when it is: the frame rules apply). Inactive and
    unconfigured are states a lifecycle manager chose, so OK with the state as the message; after a failed
    transition (``failure``: "configure failed: <reason>") an ERROR with the reason."""
    if state == "active":
        return None
    if failure:
        return ERROR, f"{state}: {failure}"
    what = {"unconfigured": "waiting for configure", "inactive": "frames are not processed until activated",
            "finalized": "shut down"}.get(state, "in transition")
    return OK, f"{state}: {what} (lifecycle)"


def level_of(w: Window, ready: bool, backend_warning: str | None = None, lifecycle_state: str = "active",
             failure: str = "") -> tuple[int, str]:
    """Level and reason: :func:`lifecycle_level` when the node is not active; else ERROR if the engine failed
    or every frame of the period was rejected; WARN while warming up, without input for 3 periods, with
    rejections, when the solver is slower than the input (:func:`too_slow`), drops more than half the frames,
    or when a flow of the period left more than UNRELIABLE of its pixels unexplained
    (census.reliability). ``backend_warning`` (the numpy fallback: numba missing) makes any OK a WARN and
    is appended to every other reason: it lasts as long as the process."""
    level, reason = lifecycle_level(lifecycle_state, failure) or _level_of(w, ready)
    if not backend_warning:
        return level, reason
    return (WARN, backend_warning) if level == OK else (level, f"{reason}; {backend_warning}")


def _level_of(w: Window, ready: bool) -> tuple[int, str]:
    if w.errors:
        return ERROR, f"engine failed on {w.errors} frame(s): {w.last_error}"
    if w.rejected and w.rejected >= w.received:
        return ERROR, f"all {w.rejected} frame(s) rejected: {w.last_rejection}"
    if not ready:
        return WARN, "warming up the engine"
    if w.since_input is None:
        return WARN, "no image received yet"
    if w.since_input > 3 * max(w.seconds, 1e-3):
        return WARN, f"no image for {w.since_input:.1f} s"
    if w.rejected:
        return WARN, f"{w.rejected} frame(s) rejected: {w.last_rejection}"
    if slow := too_slow(w):
        return WARN, slow
    if w.received and w.dropped > w.received / 2:
        return WARN, f"solver too slow: dropped {w.dropped} of {w.received} frames"
    if w.unreliable:
        return WARN, (f"flow unreliable on {w.unreliable} frame(s): over {100 * UNRELIABLE:.0f}% of pixels "
                      "not explained by the flow")
    return OK, "computing flow"


def _ms(values: list[float], fn: str) -> str:
    if not values:
        return "n/a"
    v = sum(values) / len(values) if fn == "mean" else max(values)
    return f"{1000.0 * v:.2f}"


def status(w: Window, *, name: str, hardware_id: str, ready: bool, backend: str, model: str,
           input_scale: float, resolution: str, backend_warning: str | None = None,
           lifecycle_state: str = "active", failure: str = "") -> DiagnosticStatus:
    """The DiagnosticStatus for one period (name is "<node name>: <task>", as diagnostic_updater does);
    ``lifecycle_state`` is the node's (flow_node.ros.lifecycle), ``failure`` the reason its last transition
    failed."""
    level, message = level_of(w, ready, backend_warning, lifecycle_state, failure)
    period = max(w.seconds, 1e-9)
    s = w.summary
    pairs = [
        ("lifecycle state", lifecycle_state),
        ("input rate (Hz)", f"{w.received / period:.2f}"),
        ("output rate (Hz)", f"{w.published / period:.2f}"),
        ("solve time mean (ms)", _ms(w.solve_times, "mean")),
        ("solve time max (ms)", _ms(w.solve_times, "max")),
        ("node overhead mean (ms)", _ms(w.overheads, "mean")),
        ("publish time mean (ms)", _ms(w.publish_times, "mean")),
        ("derived outputs mean (ms)", _ms(w.motion_times, "mean")),
        ("solver busy (%)", f"{100.0 * sum(w.solve_times) / period:.1f}"),
        ("flow magnitude mean (px)", "n/a" if s is None else f"{s.mean:.3f}"),
        ("flow magnitude p95 (px)", "n/a" if s is None else f"{s.p95:.3f}"),
        ("flow magnitude max (px)", "n/a" if s is None else f"{s.max:.3f}"),
        ("unexplained pixels (%)", "n/a" if w.unexplained is None else f"{100.0 * w.unexplained:.1f}"),
        ("unreliable frames", str(w.unreliable)),
        ("frames received", str(w.totals.received)),
        ("frames published", str(w.totals.published)),
        ("frames dropped", str(w.totals.dropped)),
        ("frames rejected", str(w.totals.rejected)),
        ("engine errors", str(w.totals.errors)),
        ("frames analysed (motion)", str(w.totals.analysed)),
        ("resets", str(w.totals.resets)),
        ("stream frames predicted", str(w.totals.predicted)),
        ("stream fallbacks (full solves)", str(w.totals.stream_fallbacks)),
        ("last stream fallback", w.last_stream_fallback or "none"),
        ("last reset", w.last_reset or "none"),
        ("last rejection", w.last_rejection or "none"),
        ("backend", backend),
        ("model", model),
        ("input scale", f"{input_scale:g}"),
        ("resolution", resolution),
    ]
    return DiagnosticStatus(level=level, name=name, message=message, hardware_id=hardware_id,
                            values=[KeyValue(key=k, value=v) for k, v in pairs])


def array(stamp: object, statuses: list[DiagnosticStatus]) -> DiagnosticArray:
    msg = DiagnosticArray(status=statuses)
    msg.header.stamp = stamp
    return msg
