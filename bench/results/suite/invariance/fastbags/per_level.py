"""Per-level AEE of ``fastest`` on the rendered tune scenes (task fastbags, issue 25; diagnosis only).

Wraps refine.solve_level to keep each solved level's flow after its warps; the ground truth is resized to the
level (flow_node.core.pyramid.resize_flow: area-averaged, vectors scaled) and compared there.

    PYTHONPATH=$PWD python bench/results/suite/invariance/fastbags/per_level.py NAMES [SCENES [SEEDS]]

NAMES as tuneset.py's. Prints, per candidate and scene kind, the mean AEE on each solved level (in that level's
pixels) and the final full-size AEE.
"""

from __future__ import annotations

import sys

import numpy as np

from flow_node.bag.synth import SynthSpec, render_frames
from flow_node.core import refine
from flow_node.core.api import FlowEstimator
from flow_node.core.pyramid import resize_flow

sys.path.insert(0, __file__.rsplit("/", 1)[0])
from tuneset import SPECS, config  # noqa: E402

RECORD: list[np.ndarray] = []
_solve = refine.solve_level


def recording(pyr, level, cfg, backend, state, on_finest, *args, **kw):  # type: ignore[no-untyped-def]
    """refine.solve_level, keeping the level's flow afterwards."""
    out = _solve(pyr, level, cfg, backend, state, on_finest, *args, **kw)
    RECORD.append(state.v.copy())
    return out


refine.solve_level = recording


def main() -> None:
    names = sys.argv[1].split(",")
    scenes = sys.argv[2].split(",") if len(sys.argv) > 2 else ["deformation", "rotation", "zoom"]
    seeds = [int(s) for s in sys.argv[3].split(",")] if len(sys.argv) > 3 else list(range(101, 109))
    for n in names:
        est = FlowEstimator(config(n))
        for scene in scenes:
            per: dict[int, list[float]] = {}
            final = []
            for seed in seeds:
                spec = SynthSpec(scene=scene, frames=6, size=(128, 96), seed=seed, **SPECS[scene])  # type: ignore[arg-type]
                frames, gts = render_frames(spec)
                for k, gt in enumerate(gts):
                    RECORD.clear()
                    flow = est.estimate(frames[k], frames[k + 1]).flow
                    final.append(float(np.hypot(*np.moveaxis(flow - gt, -1, 0)).mean()))
                    g = np.moveaxis(gt, -1, 0).astype(np.float32)
                    for v in RECORD:
                        w = v.shape[2]
                        gl = resize_flow(g, v.shape[1:])
                        per.setdefault(w, []).append(float(np.hypot(*(v - gl)).mean()))
            cols = " ".join(f"{w}px {np.mean(a):.4f}" for w, a in sorted(per.items()))
            print(f"{n} {scene}: {cols} | final {np.mean(final):.4f}", flush=True)


if __name__ == "__main__":
    main()
