"""The tuning protocol of issue 12's fusion rule: a tuning subset of ../shared/data/large plus exactly rendered
large-motion pairs, against OpenCV DIS medium, so a rule is chosen without the held-out pairs.

    python -m bench.large_tune                                   # the presets' quality -> bench/results/large_tune.json
    python -m bench.large_tune --only quality,quality:initialisation=dis_medium

Tuning pairs: blender_cube, kitti2012_000000, tartanair_a, tartanair_c (the rest -- kitti2012_000045,
tartanair_b, toy_square -- is held out) and 12 rendered pairs: the ``fast_pan`` / ``fast_objects`` scenes
(flow_bag.scenes, 640x480) with seeds 200-202, frames 0->1 and 1->2 (the bench bags use seeds 100-101).
A variant is ``PRESET[:key=value,...]``. Reported: the summed AEE on the tuning and held-out real pairs
and the mean AEE on the rendered pairs, each beside DIS medium's.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

import numpy as np

from flow_node.bag.synth import SynthSpec, render_frames
from flow_node.core.api import FlowEstimator, to_grey
from flow_node.core.config import FlowConfig
from flow_node.core.initialise import to_u8
from flow_node.core.metrics import aee

from .common import machine, write_json
from .large import DEFAULT_LARGE, RESULTS, load_large

TUNE = ("blender_cube", "kitti2012_000000", "tartanair_a", "tartanair_c")
SEEDS = (200, 201, 202)


def rendered_pairs() -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]:
    """(name, i0, i1, gt) of the rendered tuning pairs."""
    out = []
    for scene in ("fast_pan", "fast_objects"):
        for seed in SEEDS:
            frames, gts = render_frames(SynthSpec(scene=scene, frames=3, size=(640, 480), seed=seed))
            grey = [to_grey(f, "frame") for f in frames]
            out += [(f"{scene}_{seed}_{k}", grey[k], grey[k + 1], gts[k]) for k in range(2)]
    return out


def variant(spec: str) -> FlowConfig:
    preset, _, overrides = spec.partition(":")
    cfg = FlowConfig.preset(preset)
    return cfg.with_overrides(overrides.split(",")) if overrides else cfg


def main(argv: list[str] | None = None) -> int:
    import cv2

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="quality", help="comma-separated PRESET[:key=value...] variants; "
                    "separate several variants with ';'")
    args = ap.parse_args(argv)
    argv = sys.argv[1:] if argv is None else argv
    real = [(p.name, p.i0, p.i1, p.gt) for p in load_large(DEFAULT_LARGE)]
    rendered = rendered_pairs()
    dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
    methods: dict[str, Any] = {"opencv_dis_medium": lambda a, b: dis.calc(to_u8(a), to_u8(b), None)}
    for spec in args.only.split(";"):
        est = FlowEstimator(variant(spec))
        methods[spec] = lambda a, b, est=est: est.estimate(a, b).flow
    results: dict[str, Any] = {}
    for name, method in methods.items():
        per = {n: aee(method(a, b), gt) for n, a, b, gt in real + rendered}
        tune = sum(v for n, v in per.items() if n.startswith(TUNE))
        held = sum(v for n, v in per.items() if n in dict((r[0], 0) for r in real) and not n.startswith(TUNE))
        synth = float(np.mean([per[r[0]] for r in rendered]))
        results[name] = {"per_pair": per, "tune_sum": tune, "held_out_sum": held, "rendered_mean": synth}
    ref = results["opencv_dis_medium"]
    print("| method | tuning pairs (sum AEE) | / DIS medium | held-out pairs (sum) | / DIS medium | "
          "rendered pairs (mean AEE) | / DIS medium |\n|---|---|---|---|---|---|---|")
    for name, r in results.items():
        print(f"| {name} | {r['tune_sum']:.2f} | {r['tune_sum'] / ref['tune_sum']:.3f} | {r['held_out_sum']:.2f} | "
              f"{r['held_out_sum'] / ref['held_out_sum']:.3f} | {r['rendered_mean']:.3f} | "
              f"{r['rendered_mean'] / ref['rendered_mean']:.3f} |")
    write_json(RESULTS / "large_tune.json", {"command": "python -m bench.large_tune " + " ".join(argv),
                                             "machine": machine(), "results": results})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
