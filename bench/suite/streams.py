"""``python -m bench.suite.streams``: the suite's ``stream`` regime -- flow_node's stream presets (FlowStream,
as the node and ``flow_bag eval`` run them), its single-pair presets and OpenCV DIS medium and ultrafast on
the same exactly rendered sequences (bench/suite/sequences.py) or the bundled bags (``--bags``), frame by frame
in rotating order, each frame timed once (wall and CPU time); scores and ``event_ratio``: docs/suite.md,
"Streams", which also lists the commands. The process keeps freed memory as the node does
(``--malloc-defaults``: glibc's defaults); the 1-minute load is recorded before each sequence and at the end.
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig
from flow_node.core.metrics import aee
from flow_node.pipeline.stream import FlowStream, StreamSettings
from flow_node.process import keep_freed_memory

from ..common import REPO, machine, md_table, run_record, write_result, wxh
from .methods import DIS_MEDIUM, DIS_ULTRAFAST, parse_method
from .metrics import add_ratios
from .sequences import FRAMES, HELDOUT_KINDS, KINDS, Sequence, bag_sequences, sequences

RESULTS = REPO / "bench" / "results" / "suite" / "stream"
PERIOD_NS = 33_333_333  # 30 Hz stamps
# each stream preset's own single-pair solve (the preset with stream_levels 0), run beside it for event_ratio; a
# --method named PRESET+LABEL (a candidate stream schedule of PRESET) is compared with PRESET's
STREAM_BASE = {"stream_fast": "fastest", "stream_lite": "stream_lite/single"}
DEFAULT_METHODS = {"stream_fast": ("stream_fast", {}), "stream_lite": ("stream_lite", {}), "realtime": ("realtime", {}),
                   "fastest": ("fastest", {}), "stream_lite/single": ("stream_lite", {"stream_levels": 0})}


@dataclass(frozen=True)
class Runner:
    """One method over one sequence: ``start()`` before its first frame; ``step(previous, frame, t)`` returns the
    flow of the pair ending with ``frame`` (t its index; a stream's first frame: zeros) and the stream's label
    (SolveStats.stream; '' for single pairs). A ``stream`` carries state from frame to frame."""

    step: Callable[[np.ndarray, np.ndarray, int], tuple[np.ndarray, str]]
    start: Callable[[], None] = lambda: None
    kind: str = "single"


def stream_runner(config: FlowConfig) -> Runner:
    """flow_node's FlowStream with ``config`` (a stream preset); a new sequence's first frame starts a pair."""
    stream = FlowStream(StreamSettings(config=config))
    stream.warmup((240, 320))

    def step(previous: np.ndarray, frame: np.ndarray, t: int) -> tuple[np.ndarray, str]:
        out = stream.process(frame, (t + 1) * PERIOD_NS, "mono8")
        return (np.zeros(frame.shape + (2,), np.float32), "first") if out is None else (out.flow, out.stats.stream)
    return Runner(step, lambda: stream.reset("new sequence"), "stream")


def pair_runner(config: FlowConfig) -> Runner:
    """flow_node solving every pair on its own (``FlowEstimator.estimate``)."""
    estimator = FlowEstimator(config)
    estimator.warmup((240, 320))
    return Runner(lambda previous, frame, t: (estimator.estimate(previous, frame).flow, ""))


def dis_runner(preset: int) -> Runner:
    """OpenCV DIS with a preset on the 8-bit frames."""
    algo = cv2.DISOpticalFlow_create(preset)
    return Runner(lambda previous, frame, t: (algo.calc(previous, frame, None), ""))


def build(methods: Mapping[str, FlowConfig]) -> dict[str, Runner]:
    """Runners for ``methods`` (a config with ``stream_levels`` > 0 runs as a stream, else pair by pair), then
    DIS medium and ultrafast."""
    out = {n: stream_runner(c) if c.stream_levels else pair_runner(c) for n, c in methods.items()}
    out[DIS_MEDIUM] = dis_runner(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
    out[DIS_ULTRAFAST] = dis_runner(cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST)
    return out


def run_sequence(seq: Sequence, runners: Mapping[str, Runner]) -> dict[str, dict[str, list[Any]]]:
    """Every runner over ``seq``, frame by frame in rotating order: per method the per-pair AEE (None without
    ground truth), seconds and the stream's label (SolveStats.stream; '' for single pairs)."""
    names = list(runners)
    for r in runners.values():
        r.start()
    rows: dict[str, dict[str, list[Any]]] = {n: {"aee": [], "seconds": [], "cpu": [], "stream": []} for n in names}
    for n in names:  # the first frame: a stream starts its pair
        if runners[n].kind == "stream":
            runners[n].step(seq.frames[0], seq.frames[0], 0)
    for t in range(1, len(seq.frames)):
        k = t % len(names)
        for n in names[k:] + names[:k]:
            start, cpu = time.perf_counter(), time.process_time()
            flow, label = runners[n].step(seq.frames[t - 1], seq.frames[t], t)
            seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
            gt = seq.gt[t - 1]
            rows[n]["aee"].append(None if gt is None else aee(np.asarray(flow, np.float32), gt))
            rows[n]["seconds"].append(seconds)
            rows[n]["cpu"].append(cpu)
            rows[n]["stream"].append(label)
    return rows


def _mean(values: list[float | None]) -> float:
    v = [x for x in values if x is not None]
    return float(np.mean(v)) if v else float("nan")


def _kind(seq: Sequence) -> str:
    """The column a sequence is reported in: its kind (one sequence per kind and split), a bag or a held-out
    sequence (two per kind) by its name."""
    return seq.name if seq.kind == "bag" or seq.kind in HELDOUT_KINDS else seq.kind


def summarise(per_seq: dict[str, dict[str, dict[str, list[Any]]]], seqs: list[Sequence]) -> dict[str, Any]:
    """Per method: mean AEE and seconds over every pair, per kind, time and AEE ratios against DIS, the stream
    labels counted, and the event ratios (the pairs after a cut / the exposure step over the base preset's)."""
    names = list(next(iter(per_seq.values())))
    out: dict[str, Any] = {}
    for n in names:
        aees = [a for s in seqs for a in per_seq[s.name][n]["aee"]]
        secs = [x for s in seqs for x in per_seq[s.name][n]["seconds"]]
        labels = [x for s in seqs for x in per_seq[s.name][n]["stream"]]
        cpu = [x for s in seqs for x in per_seq[s.name][n].get("cpu", [])]
        out[n] = {"aee": _mean(aees), "seconds": float(np.mean(secs)), "cpu_seconds": _mean(cpu),
                  "per_kind": {_kind(s): {"aee": _mean(per_seq[s.name][n]["aee"]),
                                        "seconds": float(np.mean(per_seq[s.name][n]["seconds"]))} for s in seqs},
                  "predicted": labels.count("predicted"),
                  "fallbacks": sum(x.startswith("full") for x in labels)}
    add_ratios(out)
    for n, m in out.items():
        base = STREAM_BASE.get(n.partition("+")[0])
        if base in out:
            m["event_ratio"] = {}
            for s in (s for s in seqs if s.event > 0):
                pairs = (s.event, s.event + 1) if s.kind == "cut" else (s.event - 1, s.event)  # index t-1 of pair t
                m["event_ratio"][s.name] = [per_seq[s.name][n]["aee"][p] / per_seq[s.name][base]["aee"][p]
                                            for p in pairs]
    return out


def run(methods: Mapping[str, FlowConfig], split: str, size: tuple[int, int], kinds: tuple[str, ...] = KINDS,
        frames: int = FRAMES, log: Callable[[str], None] = print,
        source: Iterable[Sequence] | None = None) -> dict[str, Any]:
    """The regime on one split and size: ``{"methods": summary, "per_sequence": {name: rows}, ...}``; on the
    sequences of ``source`` instead if given (the bundled bags: split ``bags``)."""
    runners = build(methods)
    per_seq: dict[str, Any] = {}
    seqs = []
    load = []
    started = time.time()
    for seq in sequences(split, size, kinds, frames) if source is None else source:
        seqs.append(seq)
        load.append(os.getloadavg()[0])
        per_seq[seq.name] = run_sequence(seq, runners)
        log(f"  {seq.name}: " + ", ".join(f"{n} {_mean(r['aee']):.3f}/{1000 * np.mean(r['seconds']):.1f}ms"
                                          for n, r in per_seq[seq.name].items()))
    return {"split": split, "size": list(size), "frames": frames, "machine": machine(),
            "methods_config": {n: c.to_dict() for n, c in methods.items()}, "methods": summarise(per_seq, seqs),
            "per_sequence": per_seq, "wall_seconds": time.time() - started, "load": load + [os.getloadavg()[0]]}


def markdown(res: dict[str, Any], command: str) -> str:
    """A short table of a result: per method mean AEE, ms per frame, ratios, fallbacks, worst event ratio."""
    w, h = res["size"]
    rows = []
    for n, m in res["methods"].items():
        ev = [r for rs in m.get("event_ratio", {}).values() for r in rs]
        rows.append([n, f"{m['aee']:.3f}", f"{1000 * m['seconds']:.1f}", f"{m['time_vs_dis_medium']:.2f}",
                     f"{m['time_vs_dis_ultrafast']:.2f}", f"{m['aee_vs_dis_medium']:.2f}",
                     f"{m['predicted']} / {m['fallbacks']}", f"{max(ev):.2f}" if ev else "",
                     f"{1000 * m.get('cpu_seconds', np.nan):.1f}"])
    kinds = list(next(iter(res["methods"].values()))["per_kind"])
    lines = [f"# Stream regime, {res['split']} split, {w}x{h} (up to {res['frames']} frames per sequence)", "",
             f"`{command}`", "", *md_table(["method", "mean AEE", "ms/frame", "time vs DIS medium",
                                            "time vs DIS ultrafast", "AEE vs DIS medium", "predicted / full",
                                            "worst event ratio", "CPU ms/frame"], rows),
             "", "Mean AEE per kind:", "",
             *md_table(["method", *kinds], [[n, *(f"{m['per_kind'][k]['aee']:.3f}" for k in kinds)]
                                            for n, m in res["methods"].items()])]
    if res.get("load"):
        lines += ["", f"Load (1-min average, before each sequence and at the end): {min(res['load']):.1f}-"
                      f"{max(res['load']):.1f}" + ("; glibc's malloc defaults" if res.get("malloc_defaults") else "")]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.suite.streams", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--split", choices=("tune", "report", "heldout"), default="report",
                    help=f"heldout: motions neither of the others has ({', '.join(HELDOUT_KINDS)}), two of each")
    ap.add_argument("--size", default="320x240", help="WIDTHxHEIGHT")
    ap.add_argument("--kinds", default=",".join(KINDS), help=f"comma-separated subset of {', '.join(KINDS)}")
    ap.add_argument("--frames", type=int, default=FRAMES)
    ap.add_argument("--bags", action="store_true", help="the bundled bags (bags/) instead of rendered sequences "
                    "(--split, --size, --kinds and --frames do not apply; writes bags.{json,md})")
    ap.add_argument("--method", action="append", default=[], metavar="NAME=PRESET[,key=value...]",
                    help=f"replaces the default methods ({', '.join(DEFAULT_METHODS)})")
    ap.add_argument("--out", type=Path, default=None, help="directory for <split>_<size>.{json,md}")
    ap.add_argument("--malloc-defaults", action="store_true", help="glibc's malloc defaults (not the node's "
                    "keep_freed_memory): fresh pages for every large per-frame array")
    args = ap.parse_args(argv)
    if not args.malloc_defaults:
        keep_freed_memory()  # as the node's main() does: arrays freed by one frame serve the next
    w, h = wxh(args.size)
    methods = dict(parse_method(m) for m in args.method) or {
        n: FlowConfig.preset(p).replace(**kw) for n, (p, kw) in DEFAULT_METHODS.items()}
    if args.bags:
        seqs = list(bag_sequences())
        args.split, (w, h), args.frames = "bags", seqs[0].size, max(len(q.frames) for q in seqs)
        res = run(methods, args.split, (w, h), frames=args.frames, source=seqs)
    else:
        res = run(methods, args.split, (w, h), tuple(args.kinds.split(",")), args.frames)
    res |= {"command": run_record("bench.suite.streams", argv)["command"], "malloc_defaults": args.malloc_defaults}
    md = markdown(res, res["command"])
    write_result(args.out and args.out / ("bags" if args.bags else f"{args.split}_{w}x{h}"), res, md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
