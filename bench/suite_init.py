"""The initialisation variants on the broad suite (issue 12 through bench.suite's library API): where does
an initialisation win, and does it cost anything on small motions?

    python -m bench.suite_init                      # -> bench/results/suite_init.json
    python -m bench.suite_init --quick --regimes middlebury,fine_320

Each preset runs without and with its initialisation candidates, beside DIS ultrafast and medium, on the
same pairs of the same run; ``quality:dis_medium+confidence`` also returns the per-pixel confidence, so the
suite reports its AUSE (its time includes the confidence, a few ms).
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

import numpy as np

from flow_node.core.api import FlowEstimator
from flow_node.core.confidence import confidence
from flow_node.core.config import FlowConfig

from .common import REPO, machine, write_json
from .suite import run_suite
from .suite.data import Sample

RESULTS = REPO / "bench" / "results"
REGIMES = ("middlebury", "fine_320", "large", "bags")
VARIANTS = {"quality": ("none", "dis_medium", "dis_fast"), "balanced": ("none", "dis_fast"),
            "realtime": ("none", "dis_ultrafast"), "fastest": ("none", "dis_ultrafast")}


class WithConfidence:
    """flow_node with ``config`` returning (flow, confidence) -- the suite's confidence protocol."""

    def __init__(self, config: FlowConfig) -> None:
        self.estimator = FlowEstimator(config)
        self.estimator.warmup()

    def prepare(self, sample: Sample) -> tuple[np.ndarray, np.ndarray]:
        return sample.f0, sample.f1

    def run(self, prepared: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        from flow_node.core.api import to_grey

        flow = self.estimator.estimate(*prepared).flow
        return flow, confidence(to_grey(prepared[0]), to_grey(prepared[1]), flow)


def methods() -> dict[str, Any]:
    out: dict[str, Any] = {}
    for preset, inits in VARIANTS.items():
        for init in inits:
            out[f"{preset}:{init}"] = FlowConfig.preset(preset).replace(initialisation=init)
    out["quality:dis_medium+confidence"] = WithConfidence(FlowConfig.preset("quality").replace(
        initialisation="dis_medium"))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--regimes", default=",".join(REGIMES))
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--split", default="report", choices=("tune", "report", "all"))
    args = ap.parse_args(argv)
    argv = sys.argv[1:] if argv is None else argv
    res = run_suite(methods(), regimes=[r for r in args.regimes.split(",") if r], split=args.split,
                    quick=args.quick, peers=("dis_ultrafast", "dis_medium"))
    rows = []
    for regime, r in res["regimes"].items():
        for name, m in r["methods"].items():
            rows.append(f"| {regime} | {name} | {m['aee']:.3f} | {m.get('aee_vs_dis_medium', float('nan')):.2f} | "
                        f"{m.get('time_vs_dis_medium', float('nan')):.2f} | {m.get('ause', '-')} |")
    print("| regime | method | AEE | AEE / DIS medium | time / DIS medium | AUSE |\n|---|---|---|---|---|---|")
    print("\n".join(rows))
    write_json(RESULTS / ("suite_init_quick.json" if args.quick else "suite_init.json"),
               {"command": "python -m bench.suite_init " + " ".join(argv), "machine": machine(), "result": res})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
