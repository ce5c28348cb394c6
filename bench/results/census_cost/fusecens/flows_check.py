"""Flows of realtime and fastest, grey values on the 8 Middlebury and 7 large pairs and census on the large pairs, into
an .npz (one thread): run once on each tree, then compare the two files array for array.

    cd /tmp && PYTHONPATH=/work/main python flows_check.py /tmp/main.npz
    cd /tmp && PYTHONPATH=/work/wt-fusecens python flows_check.py /tmp/fusecens.npz
    python flows_check.py --compare /tmp/main.npz /tmp/fusecens.npz
"""

from __future__ import annotations

import sys

import numpy as np


def dump(out: str) -> None:
    from bench.suite.data import large, middlebury
    from flow_node.core import FlowEstimator
    from flow_node.core.config import FlowConfig

    small, far = middlebury(False), large(False)
    flows = {}
    for preset in ("realtime", "fastest"):
        for photometric, samples in (("normalise", small + far), ("census", far)):
            est = FlowEstimator(FlowConfig.preset(preset).replace(threads=1, photometric=photometric))
            for s in samples:
                flows[f"{preset}/{photometric}/{s.name}"] = est.estimate(s.f0, s.f1).flow
    np.savez(out, **flows)


def compare(a_path: str, b_path: str) -> None:
    a, b = np.load(a_path), np.load(b_path)
    differ = [k for k in a.files if k not in b.files or not np.array_equal(a[k], b[k])]
    print(f"{len(a.files)} flows, {len(differ)} differ: {differ}")


if __name__ == "__main__":
    if sys.argv[1] == "--compare":
        compare(sys.argv[2], sys.argv[3])
    else:
        dump(sys.argv[1])
