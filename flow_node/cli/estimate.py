"""``flow_estimate FRAME0 FRAME1 --output OUT.flo``: flow between two image files.

Prints nothing but errors unless ``--verbose``; exits 1 with a one-line reason on bad input, 2 on bad usage.
"""

from __future__ import annotations

import argparse
import sys

import cv2

from ..core import FlowConfig, FlowError, FlowEstimator, flow_to_color, read_image, write_flo
from ..core.config import MODELS, PRESETS


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="flow_estimate", description=__doc__.splitlines()[0])
    p.add_argument("frame0", help="first frame (8- or 16-bit PNG, grey or colour)")
    p.add_argument("frame1", help="second frame, same size")
    p.add_argument("--output", "-o", required=True, help="output .flo file (Middlebury format)")
    p.add_argument("--model", choices=MODELS, help="variational model (overrides preset/params)")
    p.add_argument("--preset", choices=tuple(PRESETS), help="named parameter set to start from")
    p.add_argument("--params", metavar="FILE.yaml", help="YAML parameters (plain or ROS params file)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override one parameter; repeatable")
    p.add_argument("--color", metavar="OUT.png", help="also write the Middlebury colour coding")
    p.add_argument("--max-flow", type=float, default=0.0,
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


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        cfg = config_from_args(args)
        f0, f1 = read_image(args.frame0), read_image(args.frame1)
        result = FlowEstimator(cfg).estimate(f0, f1)
        write_flo(args.output, result.flow)
        if args.color:
            bgr = flow_to_color(result.flow, args.max_flow, bgr=True)
            if not cv2.imwrite(args.color, bgr):
                raise FlowError(f"cannot write {args.color}")
    except FlowError as exc:
        print(f"flow_estimate: error: {exc}", file=sys.stderr)
        return 1
    if args.verbose:
        h, w = result.flow.shape[:2]
        print(f"{w}x{h} model={cfg.model} backend={result.backend} time={result.seconds:.3f}s "
              f"iterations={result.stats.total_iterations}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
