"""A shipped preset under the paper's evaluation protocol (bench/paper): issue 11's "paper protocol" target.

    python -m bench.paper_preset [PRESET ...]        # default: quality -> prints, writes results/paper_preset.json

Each preset runs on the 8 protocol pairs (Middlebury frame 10 and a second frame synthesised from it along
the ground truth scaled to 1 px, bench/paper/protocol.py), without and with the protocol's presmoothing
(sigma 1 px); AEE per sequence and mean.
"""

from __future__ import annotations

import sys

import numpy as np

from flow_node.core.config import FlowConfig

from .common import DEFAULT_DATA, REPO, SEQUENCES, write_json
from .paper.protocol import load_pairs
from .paper.run import Runner


def main(argv: list[str] | None = None) -> None:
    presets = (sys.argv[1:] if argv is None else argv) or ["quality"]
    pairs = load_pairs(DEFAULT_DATA, SEQUENCES)
    out: dict[str, dict] = {}
    for name in presets:
        for sigma in (0.0, 1.0):
            runner = Runner(sigma=sigma)
            per = {p.name: round(runner.score(FlowConfig.preset(name), p)["aee"], 4) for p in pairs}
            key = f"{name} presmooth {sigma:g}"
            out[key] = {"Dimetrodon": per["Dimetrodon"], "mean": round(float(np.mean(list(per.values()))), 4),
                        "per_sequence": per}
            print(key, out[key]["Dimetrodon"], out[key]["mean"], flush=True)
    write_json(REPO / "bench" / "results" / "paper_preset.json",
               {"command": "python -m bench.paper_preset " + " ".join(presets), "results": out})


if __name__ == "__main__":
    main()
