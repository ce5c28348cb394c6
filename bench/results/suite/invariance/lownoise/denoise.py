"""Task lownoise: what a practical denoiser in front of the engine would buy on the tune split's sensor_noise pairs (a
bound for a denoising fix, not a candidate): OpenCV's non-local means (fastNlMeansDenoising, h = C x the variant's known
sigma in grey levels, templates 7, search 21) on frame 2 alone ('f2') or on both frames alike ('both').

    python bench/results/suite/invariance/lownoise/denoise.py PRESET OUT.json C,...
"""

import json
import sys

import cv2
import numpy as np

from bench.suite import metrics
from bench.suite.photometric import UNCHANGED, middlebury_photometric, synthetic_photometric
from bench.suite.realexact import real_exact_photometric
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig

REGIMES = {"photometric_real": middlebury_photometric, "real_exact_photometric": real_exact_photometric,
           "photometric": synthetic_photometric}


def nlm(img: np.ndarray, h: float) -> np.ndarray:
    return cv2.fastNlMeansDenoising(img, None, h=float(h), templateWindowSize=7, searchWindowSize=21)


def main() -> None:
    preset, out, cs = sys.argv[1], sys.argv[2], [float(c) for c in sys.argv[3].split(",")]
    est = FlowEstimator(FlowConfig.preset(preset))
    res: dict = {}
    for regime, gen in REGIMES.items():
        rows: dict[str, list[float]] = {}
        for s in gen("tune", False):
            if s.variant == UNCHANGED or not s.variant.startswith("sensor_noise/"):
                continue
            sigma = float(s.variant.split()[-1])
            for c in cs:
                for how in ("f2", "both"):
                    f0 = nlm(s.f0, c * sigma) if how == "both" else s.f0
                    flow = est.estimate(f0, nlm(s.f1, c * sigma)).flow
                    rows.setdefault(f"{how} {c:g}", []).append(metrics.score_pair(flow, s.gt, s.occluded)["aee"])
        res[regime] = {k: float(np.mean(v)) for k, v in rows.items()}
        print(regime, " ".join(f"{k}: {v:.4f}" for k, v in res[regime].items()), flush=True)
    with open(out, "w") as fh:
        json.dump(res, fh, indent=1)


if __name__ == "__main__":
    main()
