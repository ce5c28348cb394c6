"""Task lownoise: candidate changes inside the census data term, by monkeypatch on the numpy reference (tune split).

    python bench/results/suite/invariance/lownoise/dataterm.py PRESET OUT.json VARIANT,... [REGIME,...]

VARIANT (each a run of the noisy and the unchanged pairs; the numpy backend, census.signature_form patched):
  base        today's form (a_k the mean of frame 0's and the warped frame 1's signature gradient)
  g0          a_k = frame 0's gradient only
  ivw         a_k = inverse-variance weighted mean of the two: beta g0 + (1 - beta) g1, beta = s1^2 / (s0^2 + s1^2),
              s_i each frame's noise std as the photometric stage measured it (census_noise.pair_noise's frames)
  ivwq        as ivw, with each frame's variance plus the 8-bit quantisation's (1/255)^2 / 12 in normalised units
  mapC        a per-pixel MAP weight on the data term: sm^2 / (sm^2 + var_rho(x)), var_rho the residual's noise variance
              from the pair's noise floor (each channel's noise std gain * (floor / K) / (s + eps), s from the RMS m of
              the pixel's channels: s / (s + eps) = m / gain), sm = C * gain the model's own residual std
  huberC      the L1 majoriser's DELTA raised per pixel to C times the residual's noise std (as for mapC): Huber at the
              noise level
  unbiasC     the majoriser's weight from max(rho^2 - C var_rho, 0) instead of rho^2 (the noise's expected share out)
  dN          the L1 majoriser's DELTA raised to N times the signature residual's noise std (both frames' noise at
              the floor's EPS: sqrt(2) * gain * K sigma g / (s + eps) -> taken as gain * sqrt(2) / K at s ~ floor)
Prints and writes mean AEE per regime for 'unchanged' and 'sensor_noise' pairs.
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np

from bench.suite import metrics
from bench.suite.photometric import UNCHANGED, middlebury_photometric, synthetic_photometric
from bench.suite.realexact import real_exact_photometric
from flow_node.core import census, engine, refine
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig

REGIMES = {"photometric_real": middlebury_photometric, "real_exact_photometric": real_exact_photometric,
           "photometric": synthetic_photometric}
_form, _make_pyramid, _census = census.signature_form, engine.make_pyramid, refine.census_problem


class V:
    name = "base"
    noise = None
    quant = 0.0
    floor = 0.0
    k = 3.0


def census_problem(c0, c1, cfg, backend, robust, eps_floor=0.0, *a, **kw):
    V.floor, V.k = eps_floor, cfg.census_noise_k
    return _census(c0, c1, cfg, backend, robust, eps_floor, *a, **kw)


def make_pyramid(*a, **k):
    V.noise = k.get("noise")
    return _make_pyramid(*a, **k)


def signature_form(f0, g0, f1, outside, v0, robust, params=census.CENSUS):
    if V.name == "base":
        return _form(f0, g0, f1, outside, v0, robust, params)
    g1 = census.signature_gradient(f1)
    beta = 0.5
    if V.name == "g0":
        beta = 1.0
    elif V.name.startswith("ivw") and V.noise is not None and V.noise.frames is not None:
        q = V.quant if V.name == "ivwq" else 0.0
        s0, s1 = (s * s + q for s in V.noise.frames)
        beta = s1 / (s0 + s1) if s0 + s1 > 0 else 0.5
    delta = params.delta
    if V.name.startswith("d") and V.noise is not None:
        delta = max(delta, float(V.name[1:]) * params.gain * np.sqrt(2.0))  # residual noise at the floor ~ gain
    ax = np.float32(beta) * g0[0] + np.float32(1 - beta) * g1[0]
    ay = np.float32(beta) * g0[1] + np.float32(1 - beta) * g1[1]
    r0 = f1 - f0
    c = r0 - ax * v0[0] - ay * v0[1]
    wk = 1.0 / np.sqrt(r0 * r0 + np.float32(delta) ** 2) if robust else np.ones_like(r0)
    if V.name.startswith("huber") and V.floor > 0 and robust:
        # the majoriser's DELTA raised per pixel to C times the residual's noise std (as for mapC)
        g = np.float32(params.gain)
        scale = np.float32(V.floor / V.k / params.eps)
        m0, m1 = (np.sqrt(np.mean(f * f, axis=0)) for f in (f0, f1))
        var = (scale * (g - m0)) ** 2 + (scale * (g - m1)) ** 2
        d2 = np.maximum(np.float32(delta) ** 2, np.float32(float(V.name[5:]) ** 2) * var)
        wk = 1.0 / np.sqrt(r0 * r0 + d2)
    if V.name.startswith("unbias") and V.floor > 0 and robust:
        # the majoriser's |rho(v0)| with the noise's expected share taken out: max(rho^2 - C var, 0) (as for mapC)
        g = np.float32(params.gain)
        scale = np.float32(V.floor / V.k / params.eps)
        m0, m1 = (np.sqrt(np.mean(f * f, axis=0)) for f in (f0, f1))
        var = (scale * (g - m0)) ** 2 + (scale * (g - m1)) ** 2
        r2 = np.maximum(r0 * r0 - np.float32(float(V.name[6:])) * var, np.float32(0.0))
        wk = 1.0 / np.sqrt(r2 + np.float32(delta) ** 2)
    if V.name.startswith("map") and V.floor > 0:
        # each channel's noise std at a pixel: gain * (floor / K) / (s + eps), s / (s + eps) = m / gain with m the
        # RMS of the pixel's channels; the residual's variance the sum of both frames'; MAP weight
        # sm^2 / (sm^2 + var), sm = c * gain the model's own residual std
        g = np.float32(params.gain)
        scale = np.float32(V.floor / V.k / params.eps)
        m0, m1 = (np.sqrt(np.mean(f * f, axis=0)) for f in (f0, f1))
        var = (scale * (g - m0)) ** 2 + (scale * (g - m1)) ** 2
        sm2 = np.float32((float(V.name[3:]) * params.gain) ** 2)
        wk = wk * (sm2 / (sm2 + var))
    wk = wk * ~outside
    wax, way = wk * ax, wk * ay
    return np.stack([(wax * ax).sum(0), (wax * ay).sum(0), (way * ay).sum(0),
                     (wax * c).sum(0), (way * c).sum(0)]).astype(np.float32)


census.signature_form, engine.make_pyramid, refine.census_problem = signature_form, make_pyramid, census_problem


def main() -> None:
    preset, out, variants = sys.argv[1], sys.argv[2], sys.argv[3].split(",")
    regimes = sys.argv[4].split(",") if len(sys.argv) > 4 else list(REGIMES)
    est = FlowEstimator(FlowConfig.preset(preset).replace(backend="numpy"))
    res: dict = {}
    t0 = time.time()
    for regime in regimes:
        samples = [s for s in REGIMES[regime]("tune", False)
                   if s.variant == UNCHANGED or s.variant.startswith("sensor_noise/")]
        for v in variants:
            V.name = v
            rows = {"unchanged": [], "sensor_noise": []}
            for s in samples:
                flow = est.estimate(s.f0, s.f1).flow
                rows[s.variant.split("/")[0]].append(metrics.score_pair(flow, s.gt, s.occluded)["aee"])
            m = {k: float(np.mean(x)) for k, x in rows.items()}
            res.setdefault(regime, {})[v] = m
            print(f"{time.time() - t0:7.1f}s {regime} {v}: unchanged {m['unchanged']:.4f} noisy "
                  f"{m['sensor_noise']:.4f} ({m['sensor_noise'] / m['unchanged']:.2f}x)", flush=True)
    with open(out, "w") as fh:
        json.dump(res, fh, indent=1)


if __name__ == "__main__":
    main()
