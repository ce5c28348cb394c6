"""What the executables share: argument parsing with one-line errors, the engine settings from a
preset, a parameter file, ``--model`` and ``--set`` overrides, and the quiet-stderr setup of a ``main()``.

Used by ``flow_estimate`` (:mod:`flow_node.cli.estimate`) and ``flow_bag`` (:mod:`flow_node.bag.cli`); a leaf:
neither command is imported from here.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import NoReturn

import cv2

from ..core.config import PRESETS, FlowConfig
from ..core.errors import one_line


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


def add_config_options(p: argparse.ArgumentParser) -> None:
    """The engine-settings options every command takes: ``--preset``, ``--params``, ``--set`` (``--model``
    differs per command and is added by each)."""
    p.add_argument("--preset", choices=tuple(PRESETS), help="named parameter set to start from")
    p.add_argument("--params", metavar="FILE.yaml", help="YAML parameters (plain or ROS params file)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override one parameter; repeatable")


def config_from_args(args: argparse.Namespace, base: FlowConfig | None = None) -> FlowConfig:
    """preset (else ``base``, else FlowConfig()), then --params file, then --model, then --set overrides
    (later wins)."""
    cfg = FlowConfig.preset(args.preset) if args.preset else (base if base is not None else FlowConfig())
    if args.params:
        cfg = FlowConfig.from_yaml(args.params, base=cfg)
    if args.model:
        cfg = cfg.replace(model=args.model)
    return cfg.with_overrides(args.overrides)


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


def silence_opencv_log() -> None:
    """Turn OpenCV's own log off (our errors say it in one line): ``cv2.utils.logging`` in OpenCV 5,
    ``cv2.setLogLevel`` in 4.x (Ubuntu 24.04's 4.6 has no ``cv2.utils.logging``); level 0 is silent in both."""
    log = getattr(cv2.utils, "logging", None)
    if log is not None:
        log.setLogLevel(log.LOG_LEVEL_SILENT)
    elif hasattr(cv2, "setLogLevel"):
        cv2.setLogLevel(0)
