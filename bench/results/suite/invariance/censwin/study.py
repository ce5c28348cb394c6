"""Census window study (task censwin, issue 25): run the suite with census signatures over other windows.

By monkeypatch only: ``census.signature`` (the numpy reference, which census.level_signature and
census.census_form call) is replaced by a variant, and the estimator's backend is the numba backend with its
census level signature and form replaced by the numpy references (the solver, pyramid, warps stay numba).
Variant ``base`` is today's signature through the same path (checks the hybrid equals the numba census).

    python bench/results/suite/invariance/censwin/study.py VARIANT OUT.json REGIMES [--quick] [--report] [--presets q,r]

(--quick applies to the synthetic and real-photograph regimes; Middlebury and bags always run every pair.)

Variants (GAIN scaled by sqrt(8 / K) so that sum_k F_k^2 stays 8 GAIN^2 for any channel count K):
  base  the 8 neighbours of 3x3, reference I(x), RMS of the 8 differences (today)
  r2    the 8 offsets 2 d_k (ring at distance 2), reference I(x) (r3: 3 d_k)
  r12   both rings (16 channels), reference I(x)
  z3    ZNCC-style over 3x3: (I(x+d) - mean_W) / (RMS_W + EPS), 9 channels (centre included)
  z5    ZNCC-style over the sparse 5x5 (centre + both rings), 17 channels
"""
from __future__ import annotations

import json
import sys
from collections.abc import Callable

import numpy as np

import flow_node.core.api as api
import flow_node.core.census as census
from flow_node.core.backends import select_backend
from flow_node.core.config import FlowConfig

RING1 = census.OFFSETS
RING2 = tuple((2 * dy, 2 * dx) for dy, dx in RING1)
RING3 = tuple((3 * dy, 3 * dx) for dy, dx in RING1)


def shifted(img: np.ndarray, dy: int, dx: int) -> np.ndarray:
    """img(x + (dy, dx)), edge values repeated outside (any |d| <= 3)."""
    h, w = img.shape
    p = np.pad(img, 3, mode="edge")
    return p[3 + dy:3 + dy + h, 3 + dx:3 + dx + w]


def centre_ref(offsets: tuple[tuple[int, int], ...]) -> Callable[..., np.ndarray]:
    def sig(img: np.ndarray, params: census.CensusParams = census.CENSUS) -> np.ndarray:
        img = img.astype(np.float32, copy=False)
        d = np.stack([shifted(img, dy, dx) - img for dy, dx in offsets])
        s = np.sqrt(np.mean(d * d, axis=0))
        gain = params.gain * np.sqrt(8.0 / len(offsets))
        return (d / (s + np.float32(params.eps)) * np.float32(gain)).astype(np.float32)
    return sig


def mean_ref(offsets: tuple[tuple[int, int], ...], eps_scale: float = 1.0) -> Callable[..., np.ndarray]:
    offsets = ((0, 0),) + offsets

    def sig(img: np.ndarray, params: census.CensusParams = census.CENSUS) -> np.ndarray:
        img = img.astype(np.float32, copy=False)
        v = np.stack([shifted(img, dy, dx) for dy, dx in offsets])
        d = v - v.mean(axis=0)
        s = np.sqrt(np.mean(d * d, axis=0))
        gain = params.gain * np.sqrt(8.0 / len(offsets))
        return (d / (s + np.float32(params.eps * eps_scale)) * np.float32(gain)).astype(np.float32)
    return sig


VARIANTS: dict[str, Callable[..., np.ndarray]] = {
    "base": centre_ref(RING1), "r2": centre_ref(RING2), "r3": centre_ref(RING3), "r12": centre_ref(RING1 + RING2),
    "z3": mean_ref(RING1), "z5": mean_ref(RING1 + RING2),
}


def install(variant: str) -> None:
    """Swap the signature and make every estimator use numba + the numpy census references."""
    census.signature = VARIANTS[variant]

    def hybrid(name: str, threads: int = 0, parallel_min_pixels: int = 0):  # noqa: ANN202
        b = select_backend("numba", threads, parallel_min_pixels).resolved()
        return b._replace(signature=census.level_signature, census_form=census.census_form)
    api.select_backend = hybrid


PRESETS = {"q": ("quality_census", dict(photometric="census", alpha=0.045), "quality"),
           "r": ("realtime_census", dict(photometric="census"), "realtime"),
           "f": ("fastest_census", dict(photometric="census"), "fastest")}


def main() -> None:
    variant, out, regimes = sys.argv[1], sys.argv[2], sys.argv[3].split(",")
    quick = "--quick" in sys.argv
    split = "report" if "--report" in sys.argv else "tune"
    presets = sys.argv[sys.argv.index("--presets") + 1].split(",") if "--presets" in sys.argv else ["q", "r"]
    install(variant)
    from bench.suite import run_suite
    methods = {PRESETS[p][0]: FlowConfig.preset(PRESETS[p][2]).replace(threads=1, **PRESETS[p][1])
               for p in presets}
    full = [r for r in regimes if r in ("middlebury", "bags")]  # fixed data: always every pair
    rest = [r for r in regimes if r not in full]
    res = {"regimes": {}}
    for names, q in ((full, False), (rest, quick)):
        if names:
            part = run_suite(methods, regimes=names, split=split, quick=q, peers=(), repeats=1, slow_repeats=1)
            res["regimes"].update(part["regimes"])
    with open(out, "w") as fh:
        json.dump(res, fh, default=str)
    for reg, r in res["regimes"].items():
        print(reg, {m: round(v["aee"], 4) for m, v in r["methods"].items()})


if __name__ == "__main__":
    main()
