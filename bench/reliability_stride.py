"""Does the reliability figure read the same at its frame-size stride (photometric.reliability_stride: ~20k
sampled pixels) as at stride 2 everywhere? On every pair of the suite's real and recorded regimes and the
exact fine textures, for three flows per pair: ``realtime``'s, zero flow and the negated flow (garbage).

    .venv/bin/python -m bench.reliability_stride --out bench/results/reliability_stride.json

Reports per regime the largest difference of the unexplained fraction and the pairs where the node's WARN
decision (fraction > photometric.UNRELIABLE) would differ.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from flow_node.core import photometric as ph
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig
from flow_node.core.numba_backend import reliability_numba

from .common import machine, write_json
from .suite import data, synthetic


def fractions(estimator: FlowEstimator, sample: Any) -> list[dict[str, Any]]:
    """The fraction at the shipped stride and at stride 2 for the pair's three flows."""
    res = estimator.estimate(sample.f0, sample.f1)
    n0, n1 = res.frames
    h, w = n0.shape
    out = []
    for label, flow in (("realtime", res.flow), ("zero", np.zeros_like(res.flow)), ("negated", -res.flow)):
        shipped = reliability_numba(n0, n1, flow)  # what the numba backend reports
        samples, ph.RELIABILITY_SAMPLES = ph.RELIABILITY_SAMPLES, h * w  # stride 2 everywhere
        try:
            dense = reliability_numba(n0, n1, flow)
        finally:
            ph.RELIABILITY_SAMPLES = samples
        out.append({"pair": sample.name, "flow": label, "size": f"{w}x{h}", "stride": ph.reliability_stride(h, w),
                    "shipped": shipped, "stride2": dense,
                    "warn_differs": (shipped > ph.UNRELIABLE) != (dense > ph.UNRELIABLE)})
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("bench/results/reliability_stride.json"))
    args = p.parse_args(argv)
    estimator = FlowEstimator(FlowConfig.preset("realtime"))
    regimes = {"middlebury": data.middlebury(False), "large": data.large(False), "bags": data.bags(False),
               "fine_320": list(synthetic.fine("report", False, (320, 240))),
               "fine_640": list(synthetic.fine("report", False, (640, 480)))}
    results: dict[str, Any] = {}
    for name, samples in regimes.items():
        rows = [r for s in samples for r in fractions(estimator, s)]
        diff = [abs(r["shipped"] - r["stride2"]) for r in rows]
        results[name] = {"pairs": len(samples), "strides": sorted({r["stride"] for r in rows}),
                         "max_abs_diff": max(diff), "mean_abs_diff": float(np.mean(diff)),
                         "warn_differs": [f"{r['pair']} {r['flow']}" for r in rows if r["warn_differs"]], "rows": rows}
        print(f"{name:10s} strides {results[name]['strides']}  |diff| max {max(diff):.4f} mean {np.mean(diff):.4f}  "
              f"WARN differs: {results[name]['warn_differs'] or 'none'}", flush=True)
    write_json(args.out, {"command": "python -m bench.reliability_stride " + " ".join(sys.argv[1:]),
                          "machine": machine(), "threshold": ph.UNRELIABLE, "results": results})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
