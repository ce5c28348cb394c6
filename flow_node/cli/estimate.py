"""``flow_estimate FRAME0 FRAME1 --output OUT.flo``: flow between two image files.

Prints nothing but errors unless ``--verbose``; exits 1 with a one-line reason on bad input, 2 on bad usage
(also one line). Outputs are all or nothing: the .flo (and the colour image) are written to temporary files
next to their targets and renamed only when everything succeeded, so a failed run leaves nothing new.
"""

from __future__ import annotations

import argparse
import errno
import os
import stat
import sys
from contextlib import suppress
from pathlib import Path

import cv2
import numpy as np

from ..core import FlowError, FlowEstimator, flow_to_color
from ..core.api import to_grey
from ..core.config import MODELS
from ..core.errors import ConfigError, FileFormatError, one_line, short_path
from ..core.flowio import flo_bytes
from ..pipeline.codec import decode_bytes
from ..process import keep_freed_memory, passive_thread_waits
from .common import (
    OneLineParser,
    add_config_options,
    config_from_args,
    finite_scale,
    native_stderr_silenced,
    silence_opencv_log,
)


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(prog="flow_estimate", description=__doc__.splitlines()[0])
    p.add_argument("frame0", help="first frame (8- or 16-bit PNG, grey or colour)")
    p.add_argument("frame1", help="second frame, same size")
    p.add_argument("--output", "-o", required=True, help="output .flo file (Middlebury format)")
    p.add_argument("--model", choices=MODELS, help="variational model (overrides preset/params)")
    add_config_options(p)
    p.add_argument("--mask", nargs="+", metavar="MASK.png",
                   help="validity mask image(s), nonzero = valid, the frames' size: one for both frames, or "
                        "two (frame 0's, frame 1's); masked pixels carry no data term")
    p.add_argument("--color", metavar="OUT.png", help="also write the Middlebury colour coding")
    p.add_argument("--max-flow", type=finite_scale, default=0.0,
                   help="colour scale in px (0 = the frame's maximum)")
    p.add_argument("--verbose", "-v", action="store_true", help="print backend, time and iterations")
    return p


def os_reason(exc: OSError) -> str:
    """The OS's words for ``exc`` ("No space left on device"), never None."""
    return exc.strerror or (os.strerror(exc.errno) if exc.errno else str(exc) or type(exc).__name__)


_KINDS = ((stat.S_ISDIR, "is a directory"), (stat.S_ISFIFO, "is a FIFO"),
          (stat.S_ISCHR, "is a character device"), (stat.S_ISBLK, "is a block device"),
          (stat.S_ISSOCK, "is a socket"))


def _not_regular(mode: int) -> str | None:
    """Why a file of this mode cannot be an input image (None for a regular file)."""
    if stat.S_ISREG(mode):
        return None
    kind = next((why for test, why in _KINDS if test(mode)), "is not a regular file")
    return f"{kind}, not an image file"


def read_frame(path: str) -> np.ndarray:
    """An image file -> float32 grey (H, W) in [0, 1]; FlowError naming the file for anything unusable
    (missing, a directory/FIFO/device, empty, undecodable, over the size limit, garbage float values)."""
    shown = short_path(path)
    try:
        why = _not_regular(os.stat(path).st_mode)
        data = Path(path).read_bytes() if why is None else b""  # never open a FIFO: it would block
    except OSError as exc:
        why = "no such file" if exc.errno == errno.ENOENT else os_reason(exc)
    if why is not None:
        raise FileFormatError(f"cannot read {shown}: {why}")
    if not data:
        raise FileFormatError(f"cannot read {shown}: the file is empty")
    return to_grey(decode_bytes(np.frombuffer(data, np.uint8), shown), shown)


def read_masks(paths: list[str] | None) -> np.ndarray | tuple[np.ndarray, np.ndarray] | None:
    """``--mask`` files as the API's mask argument: one (H, W) bool mask for both frames, or a pair; a
    mask image's pixels are valid where nonzero (any channel's grey). FlowError naming the file or count."""
    if not paths:
        return None
    if len(paths) > 2:
        raise ConfigError(f"--mask takes one file (both frames) or two (frame 0's, frame 1's), got {len(paths)}")
    masks = [read_frame(path) > 0 for path in paths]
    return masks[0] if len(masks) == 1 else (masks[0], masks[1])


def _temp_for(path: str, k: int) -> Path | None:
    """A temporary sibling of ``path`` to write first, or None to write ``path`` in place: an existing file
    that is not a regular file (/dev/stdout, /dev/full, a FIFO) must not be replaced by a rename."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        mode = stat.S_IFREG
    if not stat.S_ISREG(mode):
        return None
    return Path(path).with_name(f".flow_estimate-{os.getpid()}-{k}.tmp")


def _encode_color(path: str, bgr: np.ndarray) -> bytes:
    """The colour image encoded for ``path``'s extension; FlowError if OpenCV has no writer for it."""
    ext = Path(path).suffix
    if os.path.isdir(path):
        raise FileFormatError(f"cannot write {short_path(path)}: {os.strerror(errno.EISDIR)}")
    try:
        ok, buf = (cv2.imencode(ext, bgr) if ext and cv2.haveImageWriter(path) else (False, None))
    except cv2.error:
        ok = False
    if not ok:
        raise FileFormatError(f"cannot write {short_path(path)}: no image writer for extension "
                              f"{ext or '(none)'!r}; use .png")
    return buf.tobytes()


def write_outputs(flow: np.ndarray, output: str, color: str | None, max_flow: float) -> None:
    """Write the .flo and (if asked) the colour image, all or nothing: both are encoded in memory, written
    to temporary siblings, and renamed onto their targets only once every write succeeded."""
    files = [(output, flo_bytes(flow))]
    if color:
        files.append((color, _encode_color(color, flow_to_color(flow, max_flow, bgr=True))))
    staged: list[tuple[Path, str, str]] = []
    current = output
    try:
        for k, (current, data) in enumerate(files):
            if os.path.isdir(current):
                raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), current)
            real = os.path.realpath(current)  # a symlinked output is written through, not replaced
            tmp = _temp_for(real, k)
            if tmp is not None:
                staged.append((tmp, real, current))
            with open(tmp if tmp is not None else current, "wb") as fh:
                fh.write(data)
        for tmp, real, name in staged:
            current = name  # for the error message
            os.replace(tmp, real)
    except OSError as exc:
        raise FileFormatError(f"cannot write {short_path(current)}: {os_reason(exc)}") from None
    finally:
        for tmp, _, _ in staged:
            with suppress(OSError):
                tmp.unlink()


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    keep_freed_memory()
    passive_thread_waits()
    silence_opencv_log()
    with native_stderr_silenced():
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    try:
        cfg = config_from_args(args)
        i0, i1 = read_frame(args.frame0), read_frame(args.frame1)
        result = FlowEstimator(cfg).estimate_grey(i0, i1, mask=read_masks(args.mask))
        write_outputs(result.flow, args.output, args.color, args.max_flow)
    except FlowError as exc:
        print(f"flow_estimate: error: {one_line(exc)}", file=sys.stderr)
        return 1
    if args.verbose:
        h, w = result.flow.shape[:2]
        print(f"{w}x{h} model={cfg.model} backend={result.backend} time={result.seconds:.3f}s "
              f"iterations={result.stats.total_iterations}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
