"""A synthetic replica of issue 25's dark S-curve pair (task crush): a fine texture (synth.texture, cell 2) under a
fixed shading that takes the left 30 % of the frame to 12 % of full scale, rotated 3 degrees or shifted (1.4, -0.6) px,
both frames 8-bit; frame 2 unchanged, under smoothstep or under gamma 2 (each applied before the quantisation).
Prints the interior AEE over the whole frame and over the dark / middle / bright thirds for a preset with FlowConfig
overrides given as key=value arguments. Run from the repository root:

    PYTHONPATH=. python bench/results/suite/invariance/crush/dark_replica.py PRESET [key=value ...]
"""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[5] / "test"))
from synth import constant_flow, pair_from_flow, rotation_flow, texture  # noqa: E402

from flow_node.core.api import FlowEstimator  # noqa: E402
from flow_node.core.config import FlowConfig  # noqa: E402


def smoothstep(x: np.ndarray) -> np.ndarray:
    return x * x * (3 - 2 * x)


def q8(x: np.ndarray) -> np.ndarray:
    return (np.round(np.clip(x, 0, 1) * 255) / 255).astype(np.float32)


def main() -> None:
    preset, over = sys.argv[1], dict(a.split("=") for a in sys.argv[2:])
    cfg = FlowConfig.preset(preset).with_overrides([f"{k}={v}" for k, v in over.items()])
    h, w = 120, 160
    ys, xs = np.mgrid[0:h, 0:w]
    shade = 0.12 + 0.88 * np.clip((xs - w * 0.3) / (w * 0.4), 0, 1)
    xx = xs[6:-6, 6:-6]
    for seed, kind in ((3, "rotation"), (4, "shift")):
        tex = texture(h, w, seed=seed, cell=2)
        gt = rotation_flow(h, w, 3.0) if kind == "rotation" else constant_flow(h, w, 1.4, -0.6)
        i0, i1 = pair_from_flow(tex, gt)
        f0, f1 = q8(i0 * shade), np.clip(i1 * shade, 0, 1)
        for name, f in (("unchanged", q8(f1)), ("smoothstep", q8(smoothstep(f1))), ("gamma 2", q8(f1**2))):
            flow = FlowEstimator(cfg).estimate(f0, f).flow
            e = np.hypot(*(flow - gt).transpose(2, 0, 1))[6:-6, 6:-6]
            parts = (e[xx < w * 0.3], e[(xx >= w * 0.3) & (xx < w * 0.7)], e[xx >= w * 0.7])
            print(f"{kind:8s} {name:10s} all {e.mean():.3f}  dark {parts[0].mean():.3f}  mid {parts[1].mean():.3f}  "
                  f"bright {parts[2].mean():.3f}")


if __name__ == "__main__":
    main()
