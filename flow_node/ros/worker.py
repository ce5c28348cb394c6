"""The node's frame worker (plain Python, no rclpy): a one-slot mailbox and the thread that empties it.

The subscription callback (executor) only :meth:`Mailbox.put`\\ s the message and returns; the worker thread
warms the engine up once, then takes the newest message and hands it to the node's handler, so the executor
never runs a solve. Memory is bounded by two messages: the one being handled and the one waiting.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any


class Mailbox:
    """A one-slot queue: ``put`` replaces what is waiting (returns True if it did), ``take`` blocks."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._item: Any = None
        self._closed = False

    def put(self, item: Any) -> bool:
        with self._cond:
            replaced = self._item is not None
            self._item = item
            self._cond.notify()
            return replaced

    @property
    def waiting(self) -> bool:
        """True while an item waits to be taken."""
        with self._cond:
            return self._item is not None

    def take(self) -> Any:
        """The waiting item, or None once closed."""
        with self._cond:
            while self._item is None and not self._closed:
                self._cond.wait()
            item, self._item = self._item, None
            return None if self._closed else item

    def clear(self) -> bool:
        """Drop the waiting item; True if there was one."""
        with self._cond:
            dropped, self._item = self._item is not None, None
            return dropped

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()


class FrameWorker:
    """A daemon thread: ``warmup()`` once (if given), then ``handle(item)`` for each item taken from
    :attr:`mailbox` until :meth:`stop`. An exception of ``handle`` goes to ``failed(exc)``, which returns False
    to end the thread (the process is shutting down) or True to go on; an exception of the warm-up is kept
    in :attr:`warmup_error` (the thread goes on: frames may still work)."""

    def __init__(self, name: str, handle: Callable[[Any], None], failed: Callable[[Exception], bool],
                 warmup: Callable[[], None] | None = None) -> None:
        self.mailbox = Mailbox()
        self.warmup_error: str | None = None
        self._ready = threading.Event()
        self._handle, self._failed, self._warmup = handle, failed, warmup
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> None:
        """Start the thread (the warm-up first); does nothing if it was started already."""
        if self._thread.ident is None:
            self._thread.start()

    @property
    def ready(self) -> bool:
        """True once the warm-up is over (done or failed) and items are being handled."""
        return self._ready.is_set()

    def wait_ready(self, timeout: float | None = None) -> bool:
        return self._ready.wait(timeout)

    def _run(self) -> None:
        if self._warmup is not None:
            try:
                self._warmup()
            except Exception as exc:  # reported by the node (a managed configure fails with it)
                self.warmup_error = f"{type(exc).__name__}: {exc}"
        self._ready.set()
        while (item := self.mailbox.take()) is not None:
            try:
                self._handle(item)
            except Exception as exc:  # the worker never dies on a frame
                if not self._failed(exc):
                    break

    def stop(self, timeout: float = 30.0) -> None:
        """Close the mailbox (a waiting item is dropped) and wait for the item being handled, if any."""
        self.mailbox.close()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout=timeout)
