"""``flow_estimate FRAME0 FRAME1 --output OUT.flo``: flow between two image files (or two volumes).

Volumes (3-D flow, docs/engine.md "Volumes"): two ``.npy`` arrays (Z, Y, X) or multi-page TIFFs (one page per
slice); the flow (Z, Y, X, 3), components x, y, z in voxels, is written as ``.npy``. Any flow can be written
as ``.npy`` (an image's is (H, W, 2)).

Prints nothing but errors unless ``--verbose``; exits 1 with a one-line reason on bad input, 2 on bad usage
(also one line). Outputs are all or nothing: the .flo (and the colour image) are written to temporary files
next to their targets and renamed only when everything succeeded, so a failed run leaves nothing new.
"""

from __future__ import annotations

import argparse
import errno
import io
import os
import stat
import sys
from contextlib import suppress
from pathlib import Path

import cv2
import numpy as np

from ..core import FlowError, FlowEstimator, flow_to_color
from ..core.api import to_grey, to_planes
from ..core.config import MODELS
from ..core.errors import ConfigError, FileFormatError, one_line, short_path
from ..core.flowio import flo_parts
from ..core.volume import VOLUME_CONFIG, estimate_volume, is_volume
from ..pipeline.codec import decode_bytes
from ..process import defer_kernel_bitcode, keep_freed_memory, passive_thread_waits, skip_final_collection
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
    p.add_argument("frame0", help="first frame (8- or 16-bit PNG, grey or colour), or a volume (.npy (Z, Y, X) "
                   "or a multi-page TIFF)")
    p.add_argument("frame1", help="second frame, same size")
    p.add_argument("--output", "-o", required=True, help="output .flo file (Middlebury format), or .npy (the flow "
                   "array; required for volumes)")
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


def read_input(path: str, colour: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
    """An input file -> (a grey image (H, W) float32 in [0, 1] with its colour planes as :func:`read_planes`
    gives them, or a volume (Z, Y, X) as stored with None): a ``.npy`` array (2-D: an image) or a multi-page
    TIFF (one slice per page) is read as an array, anything else as an image. FlowError naming the file for
    anything unusable."""
    shown = short_path(path)
    suffix = Path(path).suffix.lower()
    if suffix == ".npy":
        _check_regular(path)
        try:
            arr = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise FileFormatError(f"cannot read {shown}: not a .npy array ({one_line(exc, 120)})") from None
        return (arr if is_volume(arr) or arr.ndim != 2 else to_grey(arr, shown)), None
    if suffix in (".tif", ".tiff"):
        _check_regular(path)
        if cv2.imcount(path) > 1:
            ok, pages = cv2.imreadmulti(path, flags=cv2.IMREAD_ANYDEPTH)
            if not ok or not pages or len({pg.shape for pg in pages}) != 1 or pages[0].ndim != 2:
                raise FileFormatError(f"cannot read {shown}: a multi-page TIFF needs grey pages of one size")
            return np.stack(pages), None
    return read_planes(path, colour)


def _check_regular(path: str) -> None:
    """FileFormatError unless ``path`` is an existing, non-empty regular file."""
    shown = short_path(path)
    try:
        st = os.stat(path)
    except OSError as exc:
        why = "no such file" if exc.errno == errno.ENOENT else os_reason(exc)
        raise FileFormatError(f"cannot read {shown}: {why}") from None
    why = _not_regular(st.st_mode) or ("the file is empty" if st.st_size == 0 else None)
    if why is not None:
        raise FileFormatError(f"cannot read {shown}: {why}")


def read_frame(path: str) -> np.ndarray:
    """An image file -> float32 grey (H, W) in [0, 1]; FlowError naming the file for anything unusable
    (missing, a directory/FIFO/device, empty, undecodable, over the size limit, garbage float values)."""
    return read_planes(path, colour=False)[0]


def read_planes(path: str, colour: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """An image file -> (grey (H, W), its R, G, B planes (3, H, W) or None for a grey file or ``colour``
    False), float32 in [0, 1] (api.to_planes); errors as :func:`read_frame`."""
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
    decoded = decode_bytes(np.frombuffer(data, np.uint8), shown)
    return to_planes(decoded, shown) if colour else (to_grey(decoded, shown), None)


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


def flow_parts(flow: np.ndarray, path: str) -> tuple[bytes | memoryview, ...]:
    """The flow encoded for ``path``, as the parts of the file in order: a ``.npy`` array (any flow), else a
    ``.flo`` (images only; its data part a view of ``flow``, flowio.flo_parts: not copied)."""
    if Path(path).suffix.lower() == ".npy":
        buf = io.BytesIO()
        np.save(buf, np.ascontiguousarray(flow, dtype=np.float32), allow_pickle=False)
        return (buf.getvalue(),)
    if flow.ndim != 3 or flow.shape[2] != 2:
        raise FileFormatError(f"cannot write {short_path(path)}: a volume's flow is written as .npy")
    return flo_parts(flow)


def write_outputs(flow: np.ndarray, output: str, color: str | None, max_flow: float) -> None:
    """Write the .flo and (if asked) the colour image, all or nothing: both are encoded in memory, written
    to temporary siblings, and renamed onto their targets only once every write succeeded."""
    files = [(output, flow_parts(flow, output))]
    if color:
        files.append((color, (_encode_color(color, flow_to_color(flow, max_flow, bgr=True)),)))
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
                for part in data:
                    fh.write(part)
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
    """The executable: ``argv`` None reads the command line and ends with the process (its final garbage
    collection skipped once the outputs are written: process.skip_final_collection); a list is a call from
    Python (tests, a program embedding the CLI), which leaves the process as it was besides the settings."""
    args = build_parser().parse_args(argv)
    keep_freed_memory()
    passive_thread_waits()
    defer_kernel_bitcode()
    silence_opencv_log()
    try:
        with native_stderr_silenced():
            return _run(args)
    finally:
        if argv is None:  # the process ends with this call: exit without collecting numba's object graph
            skip_final_collection()


def _run(args: argparse.Namespace) -> int:
    try:
        cfg = config_from_args(args)
        colour = cfg.colour == "channels"
        (i0, c0), (i1, c1) = read_input(args.frame0, colour), read_input(args.frame1, colour)
        if i0.ndim == 3 or i1.ndim == 3:
            if args.color or args.mask:
                raise FileFormatError("--color and --mask are for images (a volume's flow has no colour coding; "
                                      "volumes take no mask)")
            cfg = config_from_args(args, VOLUME_CONFIG)  # a volume's defaults (docs/engine.md, "Volumes")
            volume = estimate_volume(i0, i1, cfg)
            write_outputs(volume.flow, args.output, None, args.max_flow)
            if args.verbose:
                z, y, x = volume.flow.shape[:3]
                print(f"{x}x{y}x{z} model={cfg.model} backend={volume.backend} time={volume.seconds:.3f}s "
                      f"iterations={volume.iterations}")
            return 0
        channels = None if c0 is None or c1 is None else (c0, c1)
        result = FlowEstimator(cfg).estimate_grey(i0, i1, channels=channels, mask=read_masks(args.mask))
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
