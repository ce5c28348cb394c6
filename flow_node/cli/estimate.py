"""``flow_estimate FRAME0 FRAME1 --output OUT.flo``: flow between two image files.

Prints nothing but errors unless ``--verbose``; exits 1 with a one-line reason on bad input, 2 on bad usage
(also one line). Outputs are all or nothing: the .flo (and the colour image) are written to temporary files
next to their targets and renamed only when everything succeeded, so a failed run leaves nothing new.
"""

from __future__ import annotations

import argparse
import errno
import math
import os
import stat
import sys
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import NoReturn

import cv2
import numpy as np

from ..core import FlowConfig, FlowError, FlowEstimator, flow_to_color
from ..core.api import to_grey
from ..core.config import MODELS, PRESETS
from ..core.errors import FileFormatError, one_line, short_path
from ..core.flowio import flo_bytes
from ..pipeline.codec import decode_bytes
from ..process import keep_freed_memory, passive_thread_waits


class OneLineParser(argparse.ArgumentParser):
    """argparse with usage errors on a single line (``prog: error: ... (see --help)``), exit 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {one_line(message)} (see --help)\n")


def finite_scale(text: str) -> float:
    """argparse type: a finite number >= 0 (a colour scale in px; 0 = the frame's own maximum)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}") from None
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text!r}")
    return value


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(prog="flow_estimate", description=__doc__.splitlines()[0])
    p.add_argument("frame0", help="first frame (8- or 16-bit PNG, grey or colour)")
    p.add_argument("frame1", help="second frame, same size")
    p.add_argument("--output", "-o", required=True, help="output .flo file (Middlebury format)")
    p.add_argument("--model", choices=MODELS, help="variational model (overrides preset/params)")
    p.add_argument("--preset", choices=tuple(PRESETS), help="named parameter set to start from")
    p.add_argument("--params", metavar="FILE.yaml", help="YAML parameters (plain or ROS params file)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override one parameter; repeatable")
    p.add_argument("--color", metavar="OUT.png", help="also write the Middlebury colour coding")
    p.add_argument("--max-flow", type=finite_scale, default=0.0,
                   help="colour scale in px (0 = the frame's maximum)")
    p.add_argument("--verbose", "-v", action="store_true", help="print backend, time and iterations")
    return p


def config_from_args(args: argparse.Namespace) -> FlowConfig:
    """preset, then --params file, then --model, then --set overrides (later wins)."""
    cfg = FlowConfig.preset(args.preset) if args.preset else FlowConfig()
    if args.params:
        cfg = FlowConfig.from_yaml(args.params, base=cfg)
    if args.model:
        cfg = cfg.replace(model=args.model)
    return cfg.with_overrides(args.overrides)


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


@contextmanager
def native_stderr_silenced() -> Iterator[None]:
    """For an executable's main(): file descriptor 2 goes to /dev/null for the duration, while Python's own
    ``sys.stderr`` keeps writing where it did (if it is fd 2 itself, it is moved to a duplicate of it). So
    what native libraries print straight to fd 2 -- libpng's "libpng warning: iCCP: ...", past OpenCV's
    logging -- never lands between our one-line messages. Nothing changes when the process has no fd 2."""
    if sys.stderr is None:  # started without fd 2 (2>&-): fd 2 may be any file opened since; leave it be
        yield
        return
    sys.stderr.flush()
    try:
        python_on_fd2 = sys.stderr.fileno() == 2
    except (AttributeError, OSError, ValueError):  # a captured stream (tests): not on fd 2
        python_on_fd2 = False
    saved, previous = os.dup(2), sys.stderr
    if python_on_fd2:
        sys.stderr = open(os.dup(saved), "w", buffering=1, encoding=previous.encoding,  # noqa: SIM115
                          errors=previous.errors)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        yield
    finally:
        os.close(devnull)
        if python_on_fd2:
            sys.stderr.close()
            sys.stderr = previous
        previous.flush()
        os.dup2(saved, 2)
        os.close(saved)


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


def silence_opencv_log() -> None:
    """Turn OpenCV's own log off (our errors say it in one line): ``cv2.utils.logging`` in OpenCV 5,
    ``cv2.setLogLevel`` in 4.x (Ubuntu 24.04's 4.6 has no ``cv2.utils.logging``); level 0 is silent in both."""
    log = getattr(cv2.utils, "logging", None)
    if log is not None:
        log.setLogLevel(log.LOG_LEVEL_SILENT)
    elif hasattr(cv2, "setLogLevel"):
        cv2.setLogLevel(0)


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
        result = FlowEstimator(cfg).estimate_grey(i0, i1)
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
