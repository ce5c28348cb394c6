"""Running the suite: every method on every pair of every regime, timed round-robin (docs/suite.md, "Timing":
one scored run, then ``repeats`` timed rounds in rotating order, the median; ``slow_repeats`` for the slow
TV-L1 peers and any method whose scored and first timed run both exceed ``slow_seconds``), on the wall clock or the
process's CPU time (:data:`CLOCKS`; ``--clock``: docs/suite.md, "Timing")."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from flow_node.core.config import FlowConfig

from . import metrics
from .methods import DIS_MEDIUM, DIS_ULTRAFAST, PEER_NAMES, PEERS, SLOW_PEERS, Method, build, describe
from .regimes import REGIMES

QUICK_REGIMES = ("middlebury", "fine_320", "fine_640", "bit_depth", "noise", "exposure", "low_contrast",
                 "flat", "bags")


CLOCKS: dict[str, Callable[[], float]] = {"wall": time.perf_counter, "cpu": time.process_time}


def _timed(method: Method, prepared: Any, clock: Callable[[], float]) -> tuple[float, Any]:
    start = clock()
    out = method.run(prepared)
    return clock() - start, out


def run_pair(made: Mapping[str, Method], sample: Any, repeats: int, slow_repeats: int, slow_seconds: float,
             turn: int, clock: Callable[[], float] = time.perf_counter) -> dict[str, dict[str, Any]]:
    """Score and time every method on one sample (see the module docstring); ``turn`` rotates the order."""
    names = list(made)
    prepared = {n: made[n].prepare(sample) for n in names}
    times: dict[str, list[float]] = {n: [] for n in names}
    want: dict[str, int] = {}
    scores: dict[str, dict[str, Any]] = {}
    first: dict[str, float] = {}
    for n in names[turn % len(names):] + names[:turn % len(names)]:
        first[n], out = _timed(made[n], prepared[n], clock)
        scores[n] = metrics.score_pair(out, sample.gt, sample.occluded, sample.valid)
        if n in SLOW_PEERS:
            times[n].append(first[n])
        want[n] = slow_repeats if n in SLOW_PEERS else repeats
    for r in range(max(want.values())):
        k = (turn + r + 1) % len(names)
        for n in names[k:] + names[:k]:
            if len(times[n]) < want[n]:
                times[n].append(_timed(made[n], prepared[n], clock)[0])
                if r == 0 and n not in SLOW_PEERS and min(first[n], times[n][0]) > slow_seconds:
                    want[n] = max(1, slow_repeats)
    return {n: {**scores[n], "seconds": float(np.median(times[n])), "runs": len(times[n]),
                "variant": sample.variant} for n in names}


def run_regime(name: str, made: Mapping[str, Method], split: str, quick: bool, repeats: int, slow_repeats: int,
               slow_seconds: float, log: Callable[[str], None], clock: str = "wall") -> dict[str, Any]:
    """One regime: per method the per-pair scores and their summary, ratios vs DIS, similar-time flags."""
    regime = REGIMES[name]
    made = {n: m for n, m in made.items() if n not in regime.exclude}
    per: dict[str, dict[str, Any]] = {n: {} for n in made}
    start = time.perf_counter()
    pairs = []
    for k, sample in enumerate(regime.build(split, quick)):
        pairs.append({"name": sample.name, "variant": sample.variant, "size": sample.size, "bits": sample.bits})
        t0 = time.perf_counter()
        rows = run_pair(made, sample, repeats, slow_repeats, slow_seconds, k, CLOCKS[clock])
        for n, row in rows.items():
            per[n][sample.name] = row
        slowest = max(rows, key=lambda n: rows[n]["seconds"])
        log(f"  {name} {k + 1}: {sample.name} {time.perf_counter() - t0:.1f} s "
            f"(slowest {slowest} {rows[slowest]['seconds']:.2f} s)")
    methods = {n: {**metrics.summarise(per[n]), "per_pair": per[n]} for n in made}
    metrics.add_ratios(methods)
    ours = [n for n in made if n not in PEER_NAMES]
    peers = [n for n in made if n in PEER_NAMES]
    out = {"title": regime.title, "seeded": regime.seeded, "report_only": regime.report_only, "pairs": pairs,
           "methods": methods, "beaten_by": metrics.similar_time_flags(methods, ours, peers),
           "wall_seconds": time.perf_counter() - start}
    log(f"{name}: {len(pairs)} pairs, {out['wall_seconds']:.0f} s; " + ", ".join(
        f"{n} {m['aee']:.3f}" for n, m in methods.items()))
    return out


def run_suite(methods: Mapping[str, FlowConfig | Method] | None = None, regimes: Sequence[str] | None = None,
              split: str = "report", quick: bool = False, peers: Sequence[str] | None = None,
              repeats: int | None = None, slow_repeats: int | None = None, slow_seconds: float = 0.25,
              log: Callable[[str], None] = print, clock: str = "wall") -> dict[str, Any]:
    """Run the suite and return ``{"regimes": {regime: {"methods": {method: {"aee", "ae", "seconds",
    "time_vs_dis_medium", "aee_vs_dis_medium", ..., "per_variant", "per_pair"}}, "beaten_by", ...}}, ...}``.

    ``methods``: name -> FlowConfig (or a :class:`~bench.suite.methods.Method`); None = every preset and the
    plain FlowConfig() ('default'). ``regimes``: names from REGIMES (None = all; quick: all but 'large').
    ``split``: 'tune', 'report' or 'all' seeds for the synthetic regimes. ``quick``: fewer pairs and
    repeats, a 1-3 minute loop. ``peers``: default DIS ultrafast and medium when quick, all four otherwise.
    Seconds are the mean over pairs of each pair's median time on ``clock`` (:data:`CLOCKS`).
    """
    names = list(regimes) if regimes is not None else list(QUICK_REGIMES if quick else REGIMES)
    unknown = [r for r in names if r not in REGIMES]
    if unknown:
        raise ValueError(f"unknown regime(s) {', '.join(unknown)}; choose from {', '.join(REGIMES)}")
    if peers is None:
        peers = (DIS_ULTRAFAST, DIS_MEDIUM) if quick else tuple(PEERS)
    repeats = repeats if repeats is not None else (3 if quick else 5)
    slow_repeats = slow_repeats if slow_repeats is not None else 1
    made = build(methods, tuple(peers))
    started = time.time()
    res: dict[str, Any] = {
        "split": split, "quick": quick, "repeats": repeats, "slow_repeats": slow_repeats,
        "slow_seconds": slow_seconds, "clock": clock, "methods": {n: describe(m) for n, m in made.items()},
        "slow_peers": [p for p in SLOW_PEERS if p in made], "regimes": {}}
    for name in names:
        res["regimes"][name] = run_regime(name, made, split, quick, repeats, slow_repeats, slow_seconds, log,
                                           clock)
    res["wall_seconds"] = time.time() - started
    return res
