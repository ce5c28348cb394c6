"""Where a census call's time goes (issue 25): the census data term against the grey-value term, per stage.

    python -m bench.census_cost                                  # realtime, fastest, quality; 3 rounds
    python -m bench.census_cost --presets realtime --rounds 5 --out bench/results/census_cost/realtime
    python -m bench.census_cost --term main=census_median_filter=-1   # also census with the fields changed
    python -m bench.census_cost --clock cpu                      # the process's CPU time instead of wall time
    python -m bench.census_cost --data large --pairs kitti2012_000000,tartanair_a_000010_to_000009


Each preset runs with ``photometric`` ``normalise`` (grey values, the default) and ``census`` on the 8 Middlebury
pairs (``--data large``: the large-motion set, ../shared/data/large, where the initialisation and fusion run; ``--data
fine_320``: the suite's fine_320 regime's tune pairs, 320x240; ``--data bags``: the bundled bags' pairs, 128x96;
``--pairs`` a subset by name), one thread, warm (one call per pair first); each round runs every pair with each data
term in turn (the order reversed every other pair and round), and the table gives the median over rounds of each
stage's time summed over the pairs (ms). A stage's time is *exclusive*: a timed function's time minus that of the
timed functions it calls (e.g. the census form without the kernels listed beside it). The spans wrap the backend's
fields and a few module functions (:data:`SPANS`); "other" is the call's time outside every span (Python glue,
resizes, layout). The wrappers cost ~1 us per call: the totals are a few ms above an untimed call. ``--term
NAME=key=value,...`` adds a census variant (the preset with ``photometric=census`` and those fields), timed in the
same rounds: an A/B of a census change against the preset's census and grey values in one run. ``--clock cpu`` times
with the process's CPU time (time.process_time) instead of the wall clock: on a machine shared with other jobs (load
above the core count) the wall clock counts the time the process waits for a core, which lands on whichever term runs
then; CPU time does not (it still sees their cache and memory traffic). It counts every thread of the process, though:
OpenCV's second worker (DIS, some resizes) works and then spins on the other core after a parallel call, and that lands
on whichever stage runs next (the solve of the coarse levels after the initialisation, say): 26-40 ms of the large
set's ~150-200 ms per round, in both terms alike (task censlarge, bench/results/census_cost/censlarge/clocks.py).
"""

from __future__ import annotations

import argparse
import gc
import statistics
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from flow_node.core import engine, fusion, initialise, numba_census, refine
from flow_node.core.api import FlowEstimator
from flow_node.core.backends import select_backend
from flow_node.core.config import FlowConfig

from .common import md_table, run_record, write_result
from .suite import synthetic
from .suite.data import Sample, bags, large, middlebury

PRESETS = ("realtime", "fastest", "quality")
TERMS = ("normalise", "census")  # the grey-value baseline first: every ratio is against it
# backend fields timed (the backend's own functions, whatever module they live in)
BACKEND_SPANS = ("solve", "linearise", "signature", "census_form", "fuse", "consistent", "gradient", "sample",
                 "reliability", "cost_planes", "ranks")
# (module, function) timed where the engine calls it through that module's global name (the tree before the
# fused census kernel had more: `git show 9fd09d8:bench/census_cost.py`, which made `before.md`; frame 0's
# level signature was `signature_numba` before round censt: `signature/signature_numba` in older results)
SPANS: tuple[tuple[Any, str], ...] = (
    (engine, "photometric_stage"), (engine, "pair_noise"), (engine, "initialise"), (engine, "make_pyramid"),
    (refine, "median_filter"),
    (refine, "warp_source"), (numba_census, "factor_numba"), (numba_census, "census_kernel"),
    (engine, "candidates_on_level"), (initialise, "equalised"), (initialise, "dis_candidates"),
    (fusion, "planes"), (fusion, "census_planes"))
# ``fine_320``: the suite's fine_320 regime, tune seeds (12 textures at 320x240, 0.3-3 px): the suite's small frames;
# ``bags``: the bundled bags' pairs (128x96)
DATA: dict[str, Callable[[bool], list[Sample]]] = {
    "middlebury": middlebury, "large": large, "bags": bags,
    "fine_320": lambda quick: list(synthetic.fine("tune", quick, (320, 240)))}


CLOCKS: dict[str, Callable[[], float]] = {"wall": time.perf_counter, "cpu": time.process_time}
# After the warm-up every object is frozen (gc.freeze): a full collection of the cyclic collector walks every object
# of the process -- numba's and the modules', ~35 ms here -- and lands in whichever call allocates the container
# that triggers it; a run of one round per process (an A/B of two trees) then charged it to one term of one
# preset in 11 of 12 rounds (git show 4983857:bench/results/census_cost/fusecens/summary.md).
# What remains is each call's own.


class Spans:
    """Exclusive time per span name: a stack of the spans running, each one's time minus its children's
    (``clock``: :data:`CLOCKS`)."""

    def __init__(self, clock: Callable[[], float] = time.perf_counter) -> None:
        self.clock = clock
        self.seconds: dict[str, float] = {}
        self._stack: list[list[Any]] = []  # per open span: [its name, its children's time so far]

    def wrap(self, name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        """``fn`` timed as span ``name`` (``parent/name`` inside another span)."""
        def timed(*args: Any, **kwargs: Any) -> Any:
            key = f"{self._stack[-1][0]}/{name}" if self._stack else name
            self._stack.append([name, 0.0])
            start = self.clock()
            try:
                return fn(*args, **kwargs)
            finally:
                total = self.clock() - start
                children = self._stack.pop()[1]
                self.seconds[key] = self.seconds.get(key, 0.0) + total - children
                if self._stack:
                    self._stack[-1][1] += total
        return timed


@contextmanager
def patched(spans: Spans) -> Iterator[None]:
    """The module functions of :data:`SPANS` wrapped for the block."""
    saved = [(m, n, getattr(m, n)) for m, n in SPANS if hasattr(m, n)]  # (an older tree may lack some)
    for m, n, fn in saved:
        setattr(m, n, spans.wrap(n, fn))
    try:
        yield
    finally:
        for m, n, fn in saved:
            setattr(m, n, fn)


def timed_estimator(cfg: FlowConfig, spans: Spans) -> FlowEstimator:
    """An estimator for ``cfg`` whose backend's :data:`BACKEND_SPANS` fields and B-spline prefilter are timed into
    ``spans``."""
    backend = select_backend(cfg.backend, cfg.threads, cfg.parallel_min_pixels).resolved()
    fields = {f: spans.wrap(f, getattr(backend, f)) for f in BACKEND_SPANS if hasattr(backend, f)}
    warper = backend.warper._replace(prefilter=spans.wrap("prefilter", backend.warper.prefilter))
    return FlowEstimator(cfg, backend=backend._replace(warper=warper, **fields))


def parse_terms(specs: list[str]) -> dict[str, dict[str, str]]:
    """The data terms timed: name -> the preset's fields changed (:data:`TERMS`' photometric mode, then each
    ``NAME=key=value,...`` of ``--term`` as census with those fields)."""
    terms: dict[str, dict[str, str]] = {t: {"photometric": t} for t in TERMS}
    for spec in specs:
        name, _, fields = spec.partition("=")
        if not name or name in terms or "=" not in fields:
            raise SystemExit(f"--term wants NAME=key=value[,key=value...] with a new NAME, got {spec!r}")
        terms[name] = {"photometric": "census", **dict(f.split("=", 1) for f in fields.split(","))}
    return terms


def run(presets: list[str], rounds: int, terms: dict[str, dict[str, str]] | None = None,
        clock: str = "wall", data: str = "middlebury", pairs: list[str] | None = None) -> dict[str, Any]:
    """Per preset and data term (:func:`parse_terms`; default :data:`TERMS`), per round: {stage: seconds summed over
    the pairs, 'total': seconds} on ``clock`` (:data:`CLOCKS`); the pairs of ``data`` (:data:`DATA`), those named in
    ``pairs`` when given."""
    tick = CLOCKS[clock]
    terms = parse_terms([]) if terms is None else terms
    names = tuple(terms)
    samples = [s for s in DATA[data](False) if not pairs or s.name in pairs]
    if not samples:
        raise SystemExit(f"no {data} pair named {pairs}")
    out: dict[str, Any] = {}
    for preset in presets:
        spans = {t: Spans(tick) for t in names}
        ests = {t: timed_estimator(FlowConfig.preset(preset).replace(threads=1).with_overrides(
            f"{k}={v}" for k, v in terms[t].items()), spans[t]) for t in names}
        rows: dict[str, list[dict[str, float]]] = {t: [] for t in names}
        with patched(spans["normalise"]):  # warm-up: compile or load every kernel, touch the scratch arrays
            for s in samples:
                for t in names:
                    ests[t].estimate(s.f0, s.f1)
        gc.collect()  # every object so far (numba's, the modules') out of the cyclic collector's reach (CLOCKS)
        gc.freeze()
        for r in range(rounds):
            totals = dict.fromkeys(names, 0.0)
            for t in names:
                spans[t].seconds.clear()
            for k, s in enumerate(samples):
                for t in (names if (k + r) % 2 == 0 else names[::-1]):
                    with patched(spans[t]):
                        start = tick()
                        ests[t].estimate(s.f0, s.f1)
                        totals[t] += tick() - start
            for t in names:
                rows[t].append({**spans[t].seconds, "total": totals[t]})
        out[preset] = rows
    return out


def median_row(rounds: list[dict[str, float]]) -> dict[str, float]:
    """Per stage the median over rounds (a stage missing from a round counts 0), with 'other' = total minus the
    stages, per round."""
    names = sorted({k for r in rounds for k in r})
    other = [r["total"] - sum(v for k, v in r.items() if k != "total") for r in rounds]
    row = {k: statistics.median(r.get(k, 0.0) for r in rounds) for k in names}
    row["other"] = statistics.median(other)
    return row


def ratio(rows: dict[str, list[dict[str, float]]], term: str) -> tuple[float, float]:
    """``term``'s time over the grey values' (normalise): the median of the rounds' ratios, and that of their fastest
    rounds."""
    grey, other = rows["normalise"], rows[term]
    return (statistics.median(c["total"] / g["total"] for g, c in zip(grey, other, strict=True)),
            min(r["total"] for r in other) / min(r["total"] for r in grey))


def markdown(result: dict[str, Any], record: dict[str, Any]) -> str:
    lines = [f"# Census vs grey values, per stage (`{record['command']}`)", "",
             f"{record['started']}, load {record['load_average_start']}; ms summed over the "
             f"{record.get('pairs', '8 Middlebury')} pairs, "
             "one thread, median over rounds; exclusive times (bench/census_cost.py), clock "
             f"{record.get('clock', 'wall')}.", ""]
    for preset, rows in result.items():
        names = list(rows)
        terms = [t for t in names if t != "normalise"]
        med = {t: median_row(rows[t]) for t in names}
        stages = sorted({k for t in names for k in med[t]} - {"total", "other"},
                        key=lambda k: -max(med[t].get(k, 0.0) for t in names)) + ["other", "total"]
        ratios = "; ".join(f"{t} / grey {m:.2f}x (fastest rounds {f:.2f}x)" for t in terms for m, f in [ratio(rows, t)])
        lines += [f"## {preset}: {ratios} (median of the rounds' ratios)", ""]
        lines += md_table(["stage", "grey ms"] + [f"{t} ms" for t in terms] + [f"{terms[0]} share"],
                          [[k, f"{1e3 * med['normalise'].get(k, 0.0):.1f}"]
                           + [f"{1e3 * med[t].get(k, 0.0):.1f}" for t in terms]
                           + [f"{med[terms[0]].get(k, 0.0) / med[terms[0]]['total']:.0%}"] for k in stages], right=True)
        lines.append("")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--presets", default=",".join(PRESETS))
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--out", type=Path, default=None, help="result stem (.json and .md); default: print only")
    ap.add_argument("--term", action="append", default=[], metavar="NAME=key=value[,key=value...]",
                    help="also time census with these fields (repeatable)")
    ap.add_argument("--clock", choices=tuple(CLOCKS), default="wall",
                    help="wall clock, or the process's CPU time (robust to other jobs' load)")
    ap.add_argument("--data", choices=tuple(DATA), default="middlebury")
    ap.add_argument("--pairs", default="", help="comma-separated pair names of --data (default: all)")
    args = ap.parse_args(argv)
    pairs = [p for p in args.pairs.split(",") if p]
    record = {**run_record("bench.census_cost", argv), "clock": args.clock,
              "pairs": ", ".join(pairs) if pairs else ("8 Middlebury" if args.data == "middlebury" else args.data)}
    result = run(args.presets.split(","), args.rounds, parse_terms(args.term), args.clock, args.data, pairs)
    write_result(args.out, {**record, "rounds": result}, markdown(result, record))


if __name__ == "__main__":
    main()
