"""`flow_bag eval`: replay a bag through the node's per-frame pipeline and write an output bag and a report.

Every image goes through :mod:`flow_node.pipeline` exactly as the node does it (codec decode, then
``FlowStream.process``), once per model, so the flows written here are what the node would have published.
Ground truth (32FC2, flow from the previous frame, stamped like the newer frame) is matched by header stamp.
Output is written to a hidden sibling folder and renamed to ``DIR`` only when everything succeeded. The
result types (options, records, runs) are :mod:`flow_node.bag.results`'s, which the report reads too.
"""

from __future__ import annotations

import os
import shutil
import time
from collections.abc import Sequence
from contextlib import nullcontext
from pathlib import Path
from typing import Any

import numpy as np

from ..core.config import FlowConfig
from ..core.errors import InputError
from ..core.metrics import aee, angular_error, confidence_auc, valid_mask
from ..pipeline.codec import array_to_image_fields, decode, image_to_array
from ..pipeline.derived import MOTION_TOPICS, MotionAnalysis, fits_for, warm_fits
from ..pipeline.stream import FlowOutput, FlowStream, StreamSettings
from .bagio import (
    IMAGE,
    IMAGE_TYPES,
    BagError,
    BagWriter,
    RecoveredReader,
    deserialize,
    find_connections,
    image_message,
    open_bag,
    read_messages,
    stamp_ns,
)
from .motion_topics import motion_messages, motion_record, truth_errors
from .progress import FrameCallback, FrameProgress
from .results import Drawn, EvalOptions, EvalResult, FrameRecord, ModelRun

OUTPUT_TOPICS = ("flow", "magnitude", "flow_color", "confidence")
DEFAULT_GT_TOPIC = "/camera/flow_gt"
UNUSABLE = "image unusable: "  # FrameRecord.skipped prefix of an image that could not be used


def read_ground_truth(msg: Any, shape: tuple[int, int], stamp: int) -> np.ndarray:
    """A 32FC2 ground-truth message -> (H, W, 2) float32; BagError unless it matches the image ``shape``."""
    if str(msg.encoding) != "32FC2":
        raise BagError(f"ground truth at stamp {stamp} has encoding {msg.encoding}, expected 32FC2")
    try:
        gt = image_to_array(msg)
    except InputError as exc:
        raise BagError(f"ground truth at stamp {stamp} is malformed: {exc}") from exc
    if gt.shape[:2] != shape:
        raise BagError(f"ground truth at stamp {stamp} is {gt.shape[1]}x{gt.shape[0]} but the images are "
                       f"{shape[1]}x{shape[0]}")
    return gt


def choose_frames(spec: str, count: int) -> set[int]:
    """Image indices to draw: 'auto' (second, middle and last), 'all', 'none' or '3,7,...'."""
    if spec == "none" or count < 2:
        return set()
    if spec == "all":
        return set(range(1, count))
    if spec == "auto":
        return {1, max(1, count // 2), count - 1}
    try:
        return {int(x) for x in spec.split(",") if x.strip()}
    except ValueError:
        raise InputError(f"--png-frames: expected auto, all, none or indices like 1,5,9; got {spec!r}") from None


def _record(index: int, out: FlowOutput) -> FrameRecord:
    s = out.summary
    return FrameRecord(index, out.stamp_ns, out.previous_stamp_ns, out.seconds, out.stats.total_iterations,
                       {"mean": s.mean, "p95": s.p95, "max": s.max})


def _score(rec: FrameRecord, out: FlowOutput, gt: np.ndarray, analysis: MotionAnalysis | None) -> None:
    if valid_mask(gt).any():
        rec.aee, rec.ae = aee(out.flow, gt), angular_error(out.flow, gt)
        rec.confidence_auc = confidence_auc(out.confidence(), out.flow, gt)
        if analysis is not None and rec.motion is not None:
            rec.motion["vs_ground_truth"] = truth_errors(analysis, gt)


def evaluate(bag: str | Path, out_bag: Path | None, configs: Sequence[FlowConfig], opts: EvalOptions,
             on_frame: FrameCallback | None = None) -> EvalResult:
    """Run every config over the bag; write the output bag to ``out_bag`` (if given). Returns the records.
    ``on_frame(done, total)`` is called after every image (progress of a batch)."""
    settings = [StreamSettings(config=c) if opts.max_flow is None else
                StreamSettings(config=c, color_max_flow=opts.max_flow) for c in configs]
    runs = [ModelRun(c.model, c, FlowStream(s)) for c, s in zip(configs, settings, strict=True)]
    with open_bag(bag) as reader:
        gt_topic = opts.gt_topic
        if gt_topic is None and any(c.topic == DEFAULT_GT_TOPIC for c in reader.connections):
            gt_topic = DEFAULT_GT_TOPIC
        if gt_topic is not None and opts.image_topic == gt_topic:
            raise BagError(f"{bag}: {gt_topic} is the ground-truth topic; the image topic must be another one")
        gt_conns = find_connections(reader, gt_topic, (IMAGE,), "gt") if gt_topic else []
        image_conns = find_connections(reader, opts.image_topic, IMAGE_TYPES, "image",
                                       exclude=(gt_topic,) if gt_topic else ())
        total = sum(c.msgcount for c in image_conns)
        chosen = choose_frames(opts.png_frames, total)
        result = EvalResult(str(bag), image_conns[0].topic, gt_topic, 0, runs, [], settings[0].color_max_flow,
                            motion=opts.motion)
        with BagWriter(out_bag, "mcap") if out_bag is not None else nullcontext() as writer:
            if writer is not None:
                writer.add_topic(image_conns[0].topic, image_conns[0].msgtype, like=image_conns[0])
                for k, run in enumerate(runs):
                    for name in OUTPUT_TOPICS:
                        writer.add_topic(run.topic(name, k == 0), IMAGE)
                    for name, msgtype in MOTION_TOPICS.items() if opts.motion else ():
                        writer.add_topic(run.topic(name, k == 0), msgtype)
            for run in runs:
                run.stream.warmup()  # JIT compilation (numba) now, not inside the first frame's time
                if opts.motion:
                    warm_fits(fits_for(run.stream.backend))  # the derived outputs' fits, likewise
            if isinstance(reader, RecoveredReader):
                result.warnings.append(reader.recovery)
                result.recovered = reader.recovered
            _replay(reader, image_conns, gt_conns, result, chosen, writer,
                    FrameProgress(total, opts.progress, Path(bag).name, on_frame))
    if result.images == 0:
        raise BagError(f"{bag}: the image topic {result.image_topic} has no messages")
    unusable = [r for r in runs[0].records if r.skipped and r.skipped.startswith(UNUSABLE)]
    if unusable:
        result.warnings.append(f"{len(unusable)} of {result.images} images unusable and skipped (first: frame "
                               f"{unusable[0].index}, {unusable[0].skipped[len(UNUSABLE):]})")
    return result


def _replay(reader: Any, image_conns: list, gt_conns: list, result: EvalResult, chosen: set[int],
            writer: BagWriter | None, progress: FrameProgress) -> None:
    """The single pass over the bag: decode, process per model, write outputs, score against GT."""
    gts: dict[int, Any] = {}  # stamp -> GT message not yet matched
    pending: dict[int, list[tuple[FrameRecord, FlowOutput, MotionAnalysis | None]]] = {}  # stamp -> awaiting GT
    shape: tuple[int, int] | None = None
    last_stamp: int | None = None  # stamp of the previous image message, usable or not
    gt_ids = {c.id for c in gt_conns}
    for conn, t, raw in read_messages(reader, list(image_conns) + list(gt_conns)):
        msg = deserialize(raw, conn.msgtype)
        stamp = stamp_ns(msg)
        if conn.id in gt_ids:
            if stamp in pending and shape is not None:
                gt = read_ground_truth(msg, shape, stamp)
                for rec, out, analysis in pending.pop(stamp):
                    _score(rec, out, gt, analysis)
                _keep_gt(result, stamp, gt)
            else:
                gts[stamp] = msg
            continue
        index = result.images
        result.images += 1
        previous, last_stamp = last_stamp, stamp
        if writer is not None:
            writer.write_raw(result.image_topic, t, raw)
        try:
            frame, label = decode(msg)
        except InputError as exc:
            for run in result.runs:
                run.records.append(FrameRecord(index, stamp, skipped=f"{UNUSABLE}{exc}"))
            progress.update(result.images)
            continue
        shape = frame.shape[:2]
        draw = Drawn(index, stamp, frame) if index in chosen else None
        gt = read_ground_truth(gts.pop(stamp), shape, stamp) if stamp in gts else None
        waiting = []
        for k, run in enumerate(result.runs):
            try:
                out = run.stream.process(frame, stamp, label)
            except InputError as exc:
                run.records.append(FrameRecord(index, stamp, skipped=f"{UNUSABLE}{exc}"))
                continue
            if out is None:
                run.records.append(FrameRecord(index, stamp, skipped=run.stream.last_reset_reason))
                run.detector.reset()
                continue
            rec = _record(index, out)
            run.records.append(rec)
            analysis = MotionAnalysis.of(out) if result.motion else None
            if analysis is not None:
                rec.motion = motion_record(analysis, run.detector)
            if writer is not None:
                _write_outputs(writer, run, k == 0, t, msg.header, out)
            if writer is not None and analysis is not None and rec.motion is not None:
                for name, m in motion_messages(msg.header, analysis, rec.motion["detected"]):
                    writer.write(run.topic(name, k == 0), t, m)
            if draw is not None:
                draw.flows[run.label] = out.flow
            if out.previous_stamp_ns != previous:
                rec.note = "pair spans an unusable image: not scored against the ground truth"
            elif gt is not None:
                _score(rec, out, gt, analysis)
            else:
                waiting.append((rec, out, analysis))
        if waiting and gt_conns:
            pending[stamp] = waiting
        if draw is not None:
            draw.gt = gt
            result.drawn.append(draw)
        progress.update(result.images)
    progress.close()


def _keep_gt(result: EvalResult, stamp: int, gt: np.ndarray) -> None:
    """Attach a ground truth that arrived after its image to the drawn frame with that stamp, if any."""
    for d in result.drawn:
        if d.stamp_ns == stamp and d.gt is None:
            d.gt = gt


def _write_outputs(writer: BagWriter, run: ModelRun, primary: bool, t: int, hdr: Any, out: FlowOutput) -> None:
    """The node's four output messages, with the input header."""
    arrays = (("flow", out.flow, "32FC2"), ("magnitude", out.magnitude, "32FC1"),
              ("flow_color", out.color(), "bgr8"), ("confidence", out.confidence(), "32FC1"))
    for name, arr, enc in arrays:
        writer.write(run.topic(name, primary), t, image_message(hdr, array_to_image_fields(arr, enc)))


def run_eval(bag: str | Path, output: str | Path, configs: Sequence[FlowConfig], opts: EvalOptions,
             on_frame: FrameCallback | None = None) -> EvalResult:
    """Evaluate and write ``output``/{bag/, report.json, report.md, *.png}; all or nothing."""
    from .report import write_report

    out = Path(output)
    if out.exists() and not out.is_dir():
        raise BagError(f"output {out} exists and is not a folder")
    tmp = out.with_name(f".{out.name}.partial-{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    try:
        start = time.monotonic()
        result = evaluate(bag, tmp / "bag", configs, opts, on_frame)
        result.wall_seconds = time.monotonic() - start
        _rename_storage(tmp / "bag")
        write_report(result, tmp)
        if out.exists():
            shutil.rmtree(out)
        tmp.rename(out)
    except BagError as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if str(bag) in str(exc):
            raise
        raise BagError(f"{bag}: {exc}") from exc  # every bag error names the bag
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if opts.progress:
        from .report import summary_lines

        print("\n".join(summary_lines(result)))
    return result


def _rename_storage(folder: Path) -> None:
    """rosbags names the storage file after the folder it first had; name it bag_0.mcap as ros2 does."""
    meta = folder / "metadata.yaml"
    text = meta.read_text()
    for f in folder.glob("*.mcap"):
        if f.name != "bag_0.mcap":
            f.rename(folder / "bag_0.mcap")
            text = text.replace(f.name, "bag_0.mcap")
    meta.write_text(text)
