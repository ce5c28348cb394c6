"""``flow_bag``: recorded data — ``synth`` writes a bag with ground truth, ``eval`` replays a bag through the
node's per-frame pipeline and reports, ``play`` publishes a bag over DDS for a live node.

Exit codes: 0 success (and ``play`` stopped by Ctrl-C), 1 a one-line error (bad bag, bad parameter), 2 bad usage,
130 ``synth``/``eval`` interrupted.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from typing import TYPE_CHECKING

from .. import middleware
from ..cli.common import (
    OneLineParser,
    add_config_options,
    config_from_args,
    finite_scale,
    native_stderr_silenced,
    silence_opencv_log,
)
from ..core.config import MODELS
from ..core.errors import ConfigError, FlowError, one_line
from ..process import defer_kernel_bitcode, keep_freed_memory, passive_thread_waits

if TYPE_CHECKING:
    from ..core.config import FlowConfig
    from .results import EvalOptions


def _size(text: str) -> tuple[int, int]:
    w, sep, h = text.lower().partition("x")
    try:
        return int(w), int(h)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT, got {text!r}") from None


def build_parser() -> argparse.ArgumentParser:
    from .bagio import STORAGES  # imports rosbags: here, so that main() can say it is missing
    from .synth import ALL_SCENES, ENCODINGS, SynthSpec

    d = SynthSpec()
    p = OneLineParser(prog="flow_bag", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)

    s = sub.add_parser("synth", help="write a synthetic rosbag2 with exact ground-truth flow")
    s.add_argument("output", help="bag folder to create (must not exist)")
    s.add_argument("--scene", choices=ALL_SCENES, default=d.scene,
                   help="motion to render (approach, pan_objects: known time to contact / moving objects)")
    s.add_argument("--frames", type=int, default=d.frames, help="number of frames")
    s.add_argument("--size", type=_size, default=d.size, metavar="WxH", help="frame size in px")
    s.add_argument("--fps", type=float, default=d.fps, help="frame rate (header stamps and bag time)")
    s.add_argument("--noise", type=float, default=d.noise, metavar="SIGMA",
                   help="Gaussian noise sigma as a fraction of full scale (e.g. 0.01)")
    s.add_argument("--brightness", type=float, default=d.brightness,
                   help="relative brightness change per frame (e.g. 0.02 = 2%% brighter each frame)")
    s.add_argument("--encoding", choices=ENCODINGS, default=d.encoding,
                   help="image encoding; png/jpeg write sensor_msgs/CompressedImage on .../compressed")
    s.add_argument("--storage", choices=STORAGES, default=d.storage, help="rosbag2 storage plugin")
    s.add_argument("--seed", type=int, default=d.seed, help="random seed (same seed, same bytes)")

    e = sub.add_parser("eval", help="replay bags through the node's pipeline; write output bags and reports")
    e.add_argument("bag", nargs="+", help="rosbag2 folder (mcap or sqlite3); or several, folders of bags, globs, "
                   "or text files listing bags: a batch, evaluated in parallel on Dask")
    e.add_argument("--output", "-o", required=True,
                   help="report folder (one bag: replaced if it exists; a batch: reused, evaluated bags skipped)")
    e.add_argument("--image-topic", help="image topic (default: the bag's only Image/CompressedImage topic)")
    e.add_argument("--gt-topic", help="ground-truth flow topic, 32FC2 (default: /camera/flow_gt if present)")
    e.add_argument("--model", help=f"model, or several separated by commas: {', '.join(MODELS)}")
    add_config_options(e)
    e.add_argument("--max-flow", type=finite_scale, default=None,
                   help="colour scale in px for flow_color and PNGs (0 = each frame's maximum; "
                   "default: the node's color_max_flow default)")
    e.add_argument("--png-frames", default="auto",
                   help="frames to draw as PNG: comma-separated indices, 'all', 'none', or 'auto'")
    e.add_argument("--motion", action="store_true",
                   help="also write the derived motion outputs (/flow_node/motion/*: dominant motion, homography, "
                   "divergence, time to contact, focus of expansion, moving mask, motion detected) and report them")
    e.add_argument("--quiet", "-q", action="store_true", help="no progress bar or summary")
    e.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="batch: run on this existing Dask cluster (default: an embedded local cluster)")
    e.add_argument("--workers", type=int, metavar="N",
                   help="batch: workers of the embedded cluster (default: one per core); "
                   "several are processes, one is a thread of this process")

    y = sub.add_parser("play", help="publish a bag over DDS with its recorded timing (rclpy)")
    y.add_argument("bag", help="rosbag2 folder (mcap or sqlite3)")
    y.add_argument("--rate", type=float, default=1.0, help="playback speed factor")
    y.add_argument("--loop", action="store_true", help="play forever")
    y.add_argument("--topic-remap", action="append", default=[], metavar="OLD:=NEW",
                   help="publish topic OLD as NEW; repeatable")
    y.add_argument("--topics", nargs="+", default=[], help="play only these topics")
    y.add_argument("--wait-for-subscribers", type=float, default=0.0, metavar="SECONDS",
                   help="before starting, wait up to this long for a subscriber on every played topic")
    return p


def _models(text: str | None) -> list[str | None]:
    if not text:
        return [None]
    names = [m.strip() for m in text.split(",") if m.strip()]
    bad = [m for m in names if m not in MODELS]
    if bad or not names:
        raise ConfigError(f"unknown model {bad[0] if bad else text!r}; choose from {', '.join(MODELS)}")
    return list(dict.fromkeys(names))


def _run(args: argparse.Namespace) -> int:
    if args.command == "synth":
        from .synth import SynthSpec, write_synth_bag

        spec = SynthSpec(args.scene, args.frames, args.size, args.fps, args.noise, args.brightness,
                         args.encoding, args.storage, args.seed)
        write_synth_bag(args.output, spec)
        return 0
    if args.command == "play":
        from .play import PlaybackInterrupted, PlayOptions, parse_remap, run_play

        opts = PlayOptions(args.rate, args.loop, 1, parse_remap(args.topic_remap), tuple(args.topics),
                           args.wait_for_subscribers)
        # Ctrl-C is how a (looping) playback ends, a normal stop. The first one sets `stop`, which playback
        # checks before each message, so the count printed is exact (a KeyboardInterrupt could land between
        # a publish and its count); a second one interrupts whatever runs. Installed even when this process
        # was started with SIGINT ignored (a background job of a non-interactive shell inherits SIG_IGN).
        stop = threading.Event()

        def on_sigint(signum: int, frame: object) -> None:
            if stop.is_set():
                raise KeyboardInterrupt
            stop.set()

        signal.signal(signal.SIGINT, on_sigint)
        try:
            count = run_play(args.bag, opts, stop)
        except PlaybackInterrupted as exc:
            print(f"flow_bag play: stopped by Ctrl-C after publishing {exc.published} messages")
            return 0
        if stop.is_set():
            print(f"flow_bag play: stopped by Ctrl-C after publishing {count} messages")
            return 0
        print(f"flow_bag play: published {count} messages")
        return 0
    from .batch import is_single_bag
    from .evaluate import run_eval
    from .results import EvalOptions

    models = _models(args.model)
    args.model = None
    base = config_from_args(args)
    configs = [base if m is None else base.replace(model=m) for m in models]
    opts = EvalOptions(image_topic=args.image_topic, gt_topic=args.gt_topic, max_flow=args.max_flow,
                       png_frames=args.png_frames, progress=not args.quiet, motion=args.motion)
    if is_single_bag(args.bag) and args.scheduler is None and args.workers is None:
        result = run_eval(args.bag[0], args.output, configs, opts)
        for warning in result.warnings:
            print(f"flow_bag eval: warning: {one_line(warning)}", file=sys.stderr)
        return 0
    return _batch(args, configs, opts)


def _batch(args: argparse.Namespace, configs: list[FlowConfig], opts: EvalOptions) -> int:
    """Many bags on Dask; exit 1 (after the report is written) when any bag failed."""
    from .bagio import BagError
    from .batch import run_batch

    if args.workers is not None and args.workers < 1:
        raise ConfigError(f"--workers must be >= 1, got {args.workers}")
    outcomes = run_batch(args.bag, args.output, configs, opts, scheduler=args.scheduler, workers=args.workers)
    failed = [o for o in outcomes if o.status == "failed"]
    if not args.quiet:
        print(f"flow_bag eval: {len(outcomes)} bags: {sum(o.status == 'done' for o in outcomes)} evaluated, "
              f"{sum(o.status == 'skipped' for o in outcomes)} skipped (cached), {len(failed)} failed; "
              f"report {args.output}/report.md")
    if failed:
        raise BagError(f"{len(failed)} of {len(outcomes)} bags failed (first: {failed[0].name}: {failed[0].reason}); "
                       f"see {args.output}/report.md")
    return 0


MISSING_ROSBAGS = ("flow_bag: the rosbags package is not installed (the bag tools read and write bags with it): "
                   "pip install -r requirements-system-ros.txt (README, 'ROS 2 workspace')")


def main(argv: list[str] | None = None) -> int:
    try:
        parser = build_parser()
    except ModuleNotFoundError as exc:
        if (exc.name or "").split(".")[0] != "rosbags":
            raise
        print(MISSING_ROSBAGS, file=sys.stderr)
        return 1
    args = parser.parse_args(argv)
    keep_freed_memory()  # every command runs frame after frame: reuse the freed per-frame arrays' pages
    passive_thread_waits()
    defer_kernel_bitcode()
    try:
        if args.command == "play":  # rclpy logs through fd 2: keep it
            middleware.use_shipped_dds_profile()  # it publishes frames as a camera does (docs/node.md)
            return _run(args)
        silence_opencv_log()
        with native_stderr_silenced():  # libpng warnings while decoding compressed frames
            return _run(args)
    except FlowError as exc:
        print(f"flow_bag {args.command}: error: {one_line(exc)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"flow_bag {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
