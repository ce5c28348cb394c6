"""Throwaway (task censlarge): every flow of realtime, fastest and quality (census and grey values) on Middlebury, the
large set and the fine_320 tune pairs, hashed (sha256 of the float32 bytes): run in two trees and compare the files.
``--bags``: also the bundled bags' pairs (task fastcens).
PYTHONPATH=<tree> python bench/results/census_cost/censlarge/flows.py OUT.json [--bags]"""
from __future__ import annotations

import hashlib
import json
import sys

from bench.suite import data as sdata
from bench.suite import synthetic
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig


def main() -> None:
    sets = {"middlebury": sdata.middlebury(False), "large": sdata.large(False),
            "fine_320": list(synthetic.fine("tune", False, (320, 240)))}
    if "--bags" in sys.argv[2:]:
        sets["bags"] = sdata.bags(False)
    out = {}
    for preset in ("realtime", "fastest", "quality"):
        for term in ("normalise", "census"):
            est = FlowEstimator(FlowConfig.preset(preset).with_overrides([f"photometric={term}"]))
            for name, samples in sets.items():
                for s in samples:
                    flow = est.estimate(s.f0, s.f1).flow
                    out[f"{preset}/{term}/{name}/{s.name}"] = hashlib.sha256(flow.tobytes()).hexdigest()
    with open(sys.argv[1], "w") as f:
        json.dump(out, f, indent=0, sort_keys=True)
    print(len(out), "flows")


if __name__ == "__main__":
    main()
