"""Progress bars of ``flow_bag`` (tqdm, on stderr): the frames of one bag, and the bags of a batch."""

from __future__ import annotations

import sys
from collections.abc import Callable

from tqdm import tqdm

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
