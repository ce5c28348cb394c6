"""Progress bars of ``flow_bag`` (tqdm, on stderr): the frames of one bag, and the bags of a batch."""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from tqdm import tqdm

if TYPE_CHECKING:
    from .results import BagOutcome

FrameCallback = Callable[[int, int], None]  # (frames done, frames in the bag)


class FrameProgress:
    """Frames of one bag: a tqdm bar when ``enabled``, and ``callback(done, total)`` on every update
    (a batch worker forwards it to the client's bars). ``update`` takes the absolute count; the bar's final
    state stays on the terminal."""

    def __init__(self, total: int, enabled: bool, desc: str | None = None,
                 callback: FrameCallback | None = None) -> None:
        self.total, self.callback = total, callback
        self.bar = tqdm(total=total, desc=desc, unit="frame", disable=not enabled, file=sys.stderr,
                        dynamic_ncols=True)

    def update(self, done: int) -> None:
        """``done`` frames of ``total`` processed."""
        if not self.bar.disable:
            self.bar.update(done - self.bar.n)
        if self.callback is not None:
            self.callback(done, self.total)

    def close(self) -> None:
        self.bar.close()


class BatchProgress:
    """tqdm bars on the client: the bags done overall, and the frames of each bag being evaluated (fed by
    the workers' Dask events). Thread-safe: events arrive on the client's event-loop thread."""

    def __init__(self, total: int, enabled: bool) -> None:
        self.enabled = enabled
        self.overall = tqdm(total=total, unit="bag", desc="bags", disable=not enabled, dynamic_ncols=True)
        self._bars: dict[str, Any] = {}
        self._finished: set[str] = set()
        self._lock = threading.Lock()

    def on_event(self, event: Any) -> None:
        """Handler of PROGRESS_TOPIC events: ``(timestamp, {"name", "done", "total"})``."""
        msg = event[1] if isinstance(event, tuple) else event
        with self._lock:
            name = msg["name"]
            if not self.enabled or name in self._finished:
                return
            bar = self._bars.get(name)
            if bar is None:
                bar = self._bars[name] = tqdm(total=msg["total"], unit="frame", desc=name, leave=False,
                                              dynamic_ncols=True)
            bar.update(msg["done"] - bar.n)

    def finish(self, outcome: BagOutcome) -> None:
        """A bag is over: close its bar, count it, print a failure's reason above the bars."""
        with self._lock:
            self._finished.add(outcome.name)
            bar = self._bars.pop(outcome.name, None)
            if bar is not None:
                bar.close()
            self.overall.update(1)
            if outcome.status == "failed" and self.enabled:
                self.overall.write(f"flow_bag eval: {outcome.name}: failed: {outcome.reason}")

    def close(self) -> None:
        with self._lock:
            for bar in self._bars.values():
                bar.close()
            self.overall.close()
