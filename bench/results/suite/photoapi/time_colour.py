"""CPU time of the colour path (task photoapi): FlowEstimator.estimate and the photometric stage alone
(engine.colour_stage + engine.photometric_stage) on the RGB pairs of bench.suite's photometric_real (report split,
quick: 3 Middlebury sequences, unchanged RGB and two white balances), one thread, the flow_node on PYTHONPATH.

    python time_colour.py LABEL OUT.json [repeats] [preset]

Run it alternately on two trees (PYTHONPATH=main, PYTHONPATH=branch) and compare the medians."""

from __future__ import annotations

import inspect
import json
import sys
import time

import numpy as np

from bench.suite.photometric import middlebury_photometric
from flow_node.core import engine
from flow_node.core.api import FlowEstimator, to_planes
from flow_node.core.config import FlowConfig


def main() -> None:
    label, out = sys.argv[1], sys.argv[2]
    repeats = int(sys.argv[3]) if len(sys.argv) > 3 else 5
    preset = sys.argv[4] if len(sys.argv) > 4 else "quality"
    cfg = FlowConfig.preset(preset).replace(colour="channels", threads=1, backend="numba")
    samples = [s for s in middlebury_photometric("report", True) if s.f0.ndim == 3]
    est = FlowEstimator(cfg)
    est.warmup()
    backend = est._backend  # noqa: SLF001 (a one-off timing)
    new_api = "backend" in inspect.signature(engine.colour_stage).parameters
    res: dict[str, dict[str, list[float]]] = {}
    for s in samples:
        (i0, c0), (i1, c1) = to_planes(s.f0.astype(np.float32)), to_planes(s.f1.astype(np.float32))
        est.estimate(s.f0.astype(np.float32), s.f1.astype(np.float32))  # warm
        full, stage = [], []
        for _ in range(repeats):
            t = time.process_time()
            est.estimate(s.f0.astype(np.float32), s.f1.astype(np.float32))
            full.append(time.process_time() - t)
            t = time.process_time()
            for _ in range(10):
                with backend.running():
                    if new_api:
                        colour = engine.colour_stage(i0.shape, (c0, c1), cfg, backend)
                    else:
                        ch = engine.colour_stage(i0.shape, (c0, c1), cfg)
                        colour = ((c0, c1), ch)
                    engine.photometric_stage(i0, i1, cfg, backend, colour=colour)
            stage.append((time.process_time() - t) / 10)
        res[f"{s.name}/{s.variant}"] = {"estimate_s": full, "stage_s": stage}
        print(label, s.name, s.variant, f"{np.median(full):.3f} s", f"stage {1e3 * np.median(stage):.2f} ms",
              flush=True)
    with open(out, "w") as f:
        json.dump({"label": label, "preset": preset, "repeats": repeats, "pairs": res}, f, indent=1)


if __name__ == "__main__":
    main()
