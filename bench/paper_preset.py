"""A shipped preset under the paper's evaluation protocol (bench/paper): issue 11's "paper protocol" target.

    python -m bench.paper_preset [PRESET ...]        # default: quality -> prints, writes results/paper_preset.json

Each preset runs on the 8 protocol pairs (Middlebury frame 10 and a second frame synthesised from it along
the ground truth scaled to 1 px, bench/paper/protocol.py), without and with the protocol's presmoothing
(sigma 1 px); AEE per sequence and mean. Both second-frame renderers: ``bandlimited`` (exact for frame 1
read as a band-limited image; the target is measured on it) and ``cubic`` (the paper's OpenCV INTER_CUBIC
synthesis, whose interpolation error the engine reads as motion).
"""

from __future__ import annotations

import sys

import numpy as np

from flow_node.core.config import FlowConfig

from .common import DEFAULT_DATA, REPO, SEQUENCES, write_json
from .paper.protocol import RENDERERS, load_pairs
from .paper.run import Runner


def main(argv: list[str] | None = None) -> None:
    presets = (sys.argv[1:] if argv is None else argv) or ["quality"]
    out: dict[str, dict] = {}
    for renderer in RENDERERS:
        pairs = load_pairs(DEFAULT_DATA, SEQUENCES, renderer)
        for name, sigma in ((n, s) for n in presets for s in (0.0, 1.0)):
            runner = Runner(sigma=sigma)
            per = {p.name: round(runner.score(FlowConfig.preset(name), p)["aee"], 4) for p in pairs}
            key = f"{name} {renderer} presmooth {sigma:g}"
            out[key] = {"Dimetrodon": per["Dimetrodon"], "mean": round(float(np.mean(list(per.values()))), 4),
                        "per_sequence": per}
            print(key, out[key]["Dimetrodon"], out[key]["mean"], flush=True)
    write_json(REPO / "bench" / "results" / "paper_preset.json",
               {"command": "python -m bench.paper_preset " + " ".join(presets), "results": out})


if __name__ == "__main__":
    main()
