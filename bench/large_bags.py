"""Large-motion bags (issue 12): `flow_bag synth` bags of the fast_pan / fast_objects scenes (20-150 px per
frame, occlusions), replayed through `flow_bag eval`'s pipeline (FlowStream, as the node runs) per config,
beside OpenCV DIS medium on the same frames; temporal initialisation on and off.

    python -m bench.large_bags                          # -> bench/results/large_bags.json
    python -m bench.large_bags --size 320x240 --frames 6 --seeds 1

Per config: mean AEE over every scored pair of every bag, mean seconds per pair (engine time, as the node
reports it), mean confidence ROC AUC; DIS medium's time is measured on the same pairs in the same run.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from flow_node.bag.evaluate import evaluate
from flow_node.bag.results import EvalOptions
from flow_node.bag.synth import SynthSpec, render_frames, write_synth_bag
from flow_node.core.api import to_grey
from flow_node.core.config import FlowConfig
from flow_node.core.metrics import aee

from .common import REPO, machine, to_u8, write_json

RESULTS = REPO / "bench" / "results"
SCENES = ("fast_pan", "fast_objects")


def configs() -> dict[str, FlowConfig]:
    """What runs on the bags: quality and realtime without and with the initialisations, and with the
    previous flow carried forward (temporal_init) -- also with a shorter pyramid, the time it can save;
    realtime and fastest as shipped and refining the pairs DIS is fused on to full (half) size."""
    q, r, f = FlowConfig.preset("quality"), FlowConfig.preset("realtime"), FlowConfig.preset("fastest")
    return {
        "quality:none": q.replace(initialisation="none"),
        "quality:dis_fine": q.replace(initialisation="dis_fine"),
        "quality:dis_fine+temporal": q.replace(initialisation="dis_fine", temporal_init=1),
        "quality:dis_medium": q.replace(initialisation="dis_medium"),
        "quality:temporal": q.replace(initialisation="none", temporal_init=1),
        "quality:temporal,levels=8": q.replace(initialisation="none", temporal_init=1, levels=8),
        "realtime:none": r.replace(initialisation="none"),
        "realtime:dis_ultrafast": r.replace(initialisation="dis_ultrafast"),
        "realtime:dis_ultrafast+temporal": r.replace(initialisation="dis_ultrafast", temporal_init=1),
        # realtime refines a pair it fuses DIS on down to quarter size (init_finest_level 2); also to full size
        "realtime:dis_ultrafast,init_finest_level=0": r.replace(initialisation="dis_ultrafast", init_finest_level=0),
        "fastest:dis_ultrafast": f,
        "fastest:dis_ultrafast,init_finest_level=0": f.replace(init_finest_level=0),
    }


def dis_medium(frames: list[np.ndarray], gts: list[np.ndarray]) -> dict[str, float]:
    """OpenCV DIS medium on consecutive frames: mean AEE and seconds per pair."""
    import cv2

    algo = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
    grey = [to_u8(to_grey(f)) for f in frames]
    errs, secs = [], []
    for k, gt in enumerate(gts):
        start = time.perf_counter()
        flow = algo.calc(grey[k], grey[k + 1], None)
        secs.append(time.perf_counter() - start)
        errs.append(aee(flow, gt))
    return {"aee": float(np.mean(errs)), "seconds": float(np.mean(secs)), "pairs": len(gts)}


def run(size: tuple[int, int], frames: int, seeds: int, work: Path, only: list[str] | None = None,
        first_seed: int = 100) -> dict[str, Any]:
    """Every bag (scene x seed): DIS medium, then every config (or those named in ``only``) through
    flow_bag eval's pipeline (the first bag once more before, untimed, for the JIT compiles)."""
    cfgs = {k: v for k, v in configs().items() if not only or k in only}
    per_bag: dict[str, dict[str, Any]] = {}
    for scene in SCENES:
        for seed in range(seeds):
            spec = SynthSpec(scene=scene, frames=frames, size=size, seed=first_seed + seed, storage="mcap")
            name = f"{scene}_s{spec.seed}"
            bag = write_synth_bag(work / name, spec)
            imgs, gts = render_frames(spec)  # the frames the bag holds (same spec, same bytes)
            row: dict[str, Any] = {"opencv_dis_medium": dis_medium(imgs, gts),
                                   "mean_gt_px": float(np.mean([np.linalg.norm(g, axis=-1).mean() for g in gts]))}
            options = EvalOptions(png_frames="none", progress=False)
            if not per_bag:  # warm-up, discarded: the JIT compiles (~10 s) must not count as the first bag's time
                evaluate(bag, None, list(cfgs.values()), options)
            result = evaluate(bag, None, list(cfgs.values()), options)
            for label, run_ in zip(cfgs, result.runs, strict=True):
                scored = [r for r in run_.records if r.aee is not None]
                aucs = [r.confidence_auc for r in scored if r.confidence_auc is not None]
                row[label] = {"aee": float(np.mean([r.aee for r in scored])),
                              "seconds": float(np.mean([r.seconds for r in scored])),
                              "auc": float(np.mean(aucs)) if aucs else None, "pairs": len(scored)}
            per_bag[name] = row
            print(f"  {name}: " + ", ".join(f"{k} {v['aee']:.2f}" for k, v in row.items() if isinstance(v, dict)),
                  flush=True)
    return per_bag


def summary(per_bag: dict[str, dict[str, Any]]) -> dict[str, dict[str, float | None]]:
    """Means over bags of each method's AEE, seconds and AUC, and ratios to DIS medium."""
    methods = [k for k, v in next(iter(per_bag.values())).items() if isinstance(v, dict)]
    out: dict[str, dict[str, float | None]] = {}
    dis = per_bag_mean(per_bag, "opencv_dis_medium")
    for m in methods:
        s = per_bag_mean(per_bag, m)
        s["aee_vs_dis_medium"] = s["aee"] / dis["aee"]
        s["time_vs_dis_medium"] = s["seconds"] / dis["seconds"]
        out[m] = s
    return out


def per_bag_mean(per_bag: dict[str, dict[str, Any]], method: str) -> dict[str, float | None]:
    rows = [b[method] for b in per_bag.values()]
    aucs = [r["auc"] for r in rows if r.get("auc") is not None]
    return {"aee": float(np.mean([r["aee"] for r in rows])), "seconds": float(np.mean([r["seconds"] for r in rows])),
            "auc": float(np.mean(aucs)) if aucs else None}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="640x480", help="WxH of the rendered frames")
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--seeds", type=int, default=2, help="bags per scene (seeds first-seed, +1, ...)")
    ap.add_argument("--first-seed", type=int, default=100)
    ap.add_argument("--only", default="", help="';'-separated config labels (default: all)")
    ap.add_argument("--output", type=Path, default=RESULTS / "large_bags.json")
    args = ap.parse_args(argv)
    argv = sys.argv[1:] if argv is None else argv
    w, h = (int(x) for x in args.size.lower().split("x"))
    with tempfile.TemporaryDirectory(prefix="large_bags_") as tmp:
        per_bag = run((w, h), args.frames, args.seeds, Path(tmp), [o for o in args.only.split(";") if o],
                      args.first_seed)
    summ = summary(per_bag)
    print("| method | mean AEE | AEE / DIS medium | time / DIS medium | confidence AUC |\n|---|---|---|---|---|")
    for m, s in summ.items():
        auc = "-" if s["auc"] is None else f"{s['auc']:.3f}"
        print(f"| {m} | {s['aee']:.3f} | {s['aee_vs_dis_medium']:.2f} | {s['time_vs_dis_medium']:.2f} | {auc} |")
    write_json(args.output, {"command": "python -m bench.large_bags " + " ".join(argv), "machine": machine(),
                             "summary": summ, "per_bag": per_bag})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
