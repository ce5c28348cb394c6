"""The issue-11 targets, checked on one suite result (same run, ratios against the peers of that run).

Each check is a dict: target (text), regime, method, value, bound, met (bool), detail (the numbers).
A check whose regime or peer is missing from the run is reported as 'not run' (met None).
"""

from __future__ import annotations

from typing import Any

from .methods import DIS_MEDIUM, DIS_ULTRAFAST, MASKED_SUFFIX, PRESET_NAMES

FINE = ("fine_320", "fine_640")
EXPOSURE_BOUND = 1.3  # each gain variant's mean AEE / the same seeds' unchanged mean AEE
DEPTH_BOUND = 1.10  # 10/12/16-bit mean AEE / 8-bit mean AEE (better than 8 bit always passes)
MIDDLEBURY_BOUNDS = {"quality": 0.30, "realtime": 0.45}
MASS_METHODS = ("brightness", "mass")  # a config and the same with constraint=mass, as the run names them
MASS_RATIO = 0.5  # on the mass regime: mass AEE / brightness AEE
MASS_ELSEWHERE = 1.10  # on every other regime both ran: mass AEE / brightness AEE


def _check(target: str, regime: str, method: str, value: float | None, bound: float, detail: str) -> dict[str, Any]:
    met = None if value is None else bool(value <= bound)
    return {"target": target, "regime": regime, "method": method, "value": value, "bound": bound, "met": met,
            "detail": detail}


def _get(res: dict[str, Any], regime: str, method: str) -> dict[str, Any] | None:
    return res.get("regimes", {}).get(regime, {}).get("methods", {}).get(method)


def fine_checks(res: dict[str, Any]) -> list[dict[str, Any]]:
    """quality <= 0.8x DIS medium AEE; realtime <= DIS medium AEE at <= its time; fastest <= DIS ultrafast
    AEE at <= 2x its time; on the fine-texture regimes at 320x240 and 640x480."""
    out = []
    for regime in FINE:
        q, rt, fa = (_get(res, regime, m) for m in ("quality", "realtime", "fastest"))
        med, uf = _get(res, regime, DIS_MEDIUM), _get(res, regime, DIS_ULTRAFAST)
        if q and med:
            v = q["aee"] / med["aee"]
            out.append(_check("quality AEE <= 0.8x DIS medium", regime, "quality", v, 0.8,
                              f"{q['aee']:.4f} vs {med['aee']:.4f} px = {v:.2f}x"))
        if rt and med:
            a, t = rt["aee"] / med["aee"], rt["seconds"] / med["seconds"]
            out.append(_check("realtime AEE <= DIS medium at <= its time", regime, "realtime", max(a, t), 1.0,
                              f"AEE {rt['aee']:.4f} vs {med['aee']:.4f} px ({a:.2f}x), "
                              f"time {t:.2f}x DIS medium"))
        if fa and uf:
            a, t = fa["aee"] / uf["aee"], fa["seconds"] / uf["seconds"]
            out.append(_check("fastest AEE <= DIS ultrafast at <= 2x its time", regime, "fastest",
                              max(a, t / 2.0), 1.0, f"AEE {fa['aee']:.4f} vs {uf['aee']:.4f} px ({a:.2f}x), "
                              f"time {t:.2f}x DIS ultrafast"))
    return out


def variant_ratios(m: dict[str, Any], ref: str) -> dict[str, float] | None:
    """Each variant's mean AEE over the reference variant's (same seeds) for one method's regime result; None
    if the regime has no such reference variant."""
    per = m.get("per_variant", {})
    if ref not in per:
        return None
    return {v: d["aee"] / per[ref]["aee"] for v, d in per.items() if v != ref}


def variant_checks(res: dict[str, Any], regime: str, ref: str, bound: float, target: str) -> list[dict[str, Any]]:
    """For each preset: the worst ratio of a variant's mean AEE to the reference variant's (same seeds)."""
    out = []
    for name in PRESET_NAMES:
        m = _get(res, regime, name)
        ratios = variant_ratios(m, ref) if m else None
        if not ratios:
            continue
        base = m["per_variant"][ref]["aee"]
        worst = max(ratios, key=lambda v: ratios[v])
        detail = f"{ref} {base:.4f} px; " + ", ".join(f"{v} {r:.2f}x" for v, r in ratios.items())
        out.append(_check(target, regime, name, ratios[worst], bound, detail))
    return out


def middlebury_checks(res: dict[str, Any]) -> list[dict[str, Any]]:
    out = []
    for name, bound in MIDDLEBURY_BOUNDS.items():
        m = _get(res, "middlebury", name)
        if m:
            out.append(_check(f"Middlebury {name} mean AEE <= {bound}", "middlebury", name, m["aee"], bound,
                              f"{m['aee']:.3f} px"))
    return out


def peer_checks(res: dict[str, Any]) -> list[dict[str, Any]]:
    """No regime (large motions aside) where a peer at <= 1.5x a preset's time has a lower AEE."""
    out = []
    for regime, r in res.get("regimes", {}).items():
        if r.get("report_only"):
            continue
        for name, beaten in r.get("beaten_by", {}).items():
            if name in PRESET_NAMES:
                out.append(_check("no peer of similar time (<= 1.5x) beats the preset", regime, name,
                                  float(len(beaten)), 0.0, ", ".join(beaten) if beaten else "none"))
    return out


MASKED_BOUND, ELSEWHERE_BOUND = 0.5, 1.05  # issue 27: masked pixels' AEE <= 0.5x without the mask; elsewhere +5 %


def missing_checks(res: dict[str, Any]) -> list[dict[str, Any]]:
    """Regime ``missing``: for every method X run with and without the mask (``X+mask``), the masked pixels'
    mean AEE <= 0.5x X's, and the other pixels' within 5 %."""
    out = []
    methods = res.get("regimes", {}).get("missing", {}).get("methods", {})
    for name in methods:
        with_mask, plain = methods.get(name + MASKED_SUFFIX), methods[name]
        if with_mask is None or plain.get("aee_masked") is None:
            continue
        a = with_mask["aee_masked"] / plain["aee_masked"]
        e = with_mask["aee_elsewhere"] / plain["aee_elsewhere"]
        out.append(_check("missing: masked pixels' AEE <= 0.5x without the mask", "missing", name + MASKED_SUFFIX,
                          a, MASKED_BOUND, f"{with_mask['aee_masked']:.4f} vs {plain['aee_masked']:.4f} px"))
        out.append(_check("missing: AEE elsewhere within 5 % of without the mask", "missing", name + MASKED_SUFFIX,
                          e, ELSEWHERE_BOUND, f"{with_mask['aee_elsewhere']:.4f} vs {plain['aee_elsewhere']:.4f} px"))
    return out


def mass_checks(res: dict[str, Any]) -> list[dict[str, Any]]:
    """Issue 27: the method 'mass' (constraint=mass) <= 0.5x the method 'brightness' on the mass regime and
    within 10 % of it on each other regime both ran on."""
    out = []
    for regime in res.get("regimes", {}):
        b, m = (_get(res, regime, name) for name in MASS_METHODS)
        if not (b and m):
            continue
        bound = MASS_RATIO if regime == "mass" else MASS_ELSEWHERE
        v = m["aee"] / b["aee"]
        out.append(_check(f"mass AEE <= {bound}x brightness", regime, "mass", v, bound,
                          f"{m['aee']:.4f} vs {b['aee']:.4f} px = {v:.2f}x"))
    return out


def all_checks(res: dict[str, Any]) -> list[dict[str, Any]]:
    """Every target check the result allows."""
    return (fine_checks(res)
            + variant_checks(res, "exposure", "unchanged", EXPOSURE_BOUND,
                             "exposure: every gain's AEE <= 1.3x the unchanged pair's")
            + variant_checks(res, "bit_depth", "8 bit", DEPTH_BOUND, "10/12/16-bit AEE within 10% of 8-bit")
            + middlebury_checks(res) + peer_checks(res) + missing_checks(res) + mass_checks(res))
