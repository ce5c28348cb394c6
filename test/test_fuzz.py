"""Property-based fuzzing (hypothesis) of everything a hostile user controls: Image/CompressedImage messages
through the codec and the stream, mutated bags through ``flow_bag eval``, random ``flow_estimate`` command
lines. The invariants: no uncaught exception, no NaN/inf ever returned, written or published as a result, an
error is one line naming the input, and a failed run leaves nothing that looks like a complete output.

Deterministic: ``derandomize=True`` (examples derived from the test itself), no example database, a fixed
example count. ``FLOW_FUZZ_SCALE=N`` multiplies the counts (``make fuzz`` runs them at 20x).
"""

from __future__ import annotations

import io
import json
import os
import shutil
import struct
import tempfile
import zlib
from contextlib import redirect_stderr, redirect_stdout
from functools import lru_cache
from pathlib import Path
from types import SimpleNamespace

import cv2
import numpy as np
import small_frames
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rosbags.rosbag2 import Reader

from flow_node.bag.bagio import IMAGE, BagWriter, header, image_message
from flow_node.bag.cli import main as flow_bag
from flow_node.bag.synth import SynthSpec, write_synth_bag
from flow_node.cli.estimate import main as flow_estimate
from flow_node.core.config import MODELS
from flow_node.core.errors import InputError
from flow_node.core.flowio import read_flo
from flow_node.pipeline.codec import SUPPORTED_ENCODINGS, array_to_image_fields, decode, image_to_array
from flow_node.pipeline.stream import FlowStream, StreamSettings

SCALE = max(1, int(os.environ.get("FLOW_FUZZ_SCALE", "1")))


def fuzz(examples: int) -> settings:
    """Deterministic settings with ``examples`` (times FLOW_FUZZ_SCALE) examples."""
    return settings(max_examples=examples * SCALE, derandomize=True, database=None, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


# ------------------------------------------------------------------------------------------- messages
def _png(w: int, h: int, claim: tuple[int, int] | None = None) -> bytes:
    ok, buf = cv2.imencode(".png", (np.arange(w * h) % 251).astype(np.uint8).reshape(h, w))
    b = bytearray(buf.tobytes())
    if claim:
        b[16:24] = struct.pack(">II", *claim)
        b[29:33] = struct.pack(">I", zlib.crc32(bytes(b[12:29])))
    return bytes(b)


SPECIAL_FLOATS = st.sampled_from([np.nan, np.inf, -np.inf, 1e30, -1e30, 3.4e38, 1e6, 1e7, -1.0, 2.0, 0.5])


@st.composite
def raw_images(draw: st.DrawFn) -> SimpleNamespace:
    """An Image message with any combination of sane and broken fields (duck-typed, as the codec reads)."""
    encoding = draw(st.one_of(st.sampled_from(SUPPORTED_ENCODINGS),
                              st.text(max_size=12), st.sampled_from(["MONO8", "nv21", "32FC3", "16SC1"])))
    width = draw(st.one_of(st.integers(0, 24), st.sampled_from([-1, 100000, 2**31])))
    height = draw(st.one_of(st.integers(0, 24), st.sampled_from([-3, 70000])))
    nominal = max(0, width) * draw(st.sampled_from([1, 2, 3, 4, 6, 8]))  # bytes per pixel of some encoding
    step = draw(st.one_of(st.just(nominal), st.integers(0, 200), st.sampled_from([nominal + 3, 2**32 - 1])))
    size = draw(st.one_of(st.just(max(0, step * height)), st.integers(0, 3000)))
    size = min(size, 20000)
    data = draw(st.binary(min_size=min(size, 64), max_size=min(size, 64)))
    payload = bytearray((data * (size // max(len(data), 1) + 1))[:size]) if data else bytearray(size)
    if encoding.startswith("32F") and size >= 4 and draw(st.booleans()):
        view = np.frombuffer(payload, np.float32, count=size // 4).copy()
        view[:] = np.abs(view) % 1.0 if draw(st.booleans()) else view
        for k in draw(st.lists(st.integers(0, size // 4 - 1), max_size=4)):
            view[k] = draw(SPECIAL_FLOATS)
        payload[: view.nbytes] = view.tobytes()
    return SimpleNamespace(height=height, width=width, encoding=encoding, step=step,
                           is_bigendian=draw(st.sampled_from([0, 1, 7])), data=bytes(payload))


@st.composite
def compressed_images(draw: st.DrawFn) -> SimpleNamespace:
    """A CompressedImage: valid, truncated, bit-flipped, claiming a huge size, or garbage."""
    w, h = draw(st.integers(1, 24)), draw(st.integers(1, 24))
    kind = draw(st.sampled_from(["png", "jpeg", "claim", "garbage", "empty"]))
    if kind == "png":
        data = _png(w, h)
    elif kind == "jpeg":
        data = cv2.imencode(".jpg", np.full((h, w), 90, np.uint8))[1].tobytes()
    elif kind == "claim":
        data = _png(w, h, (draw(st.integers(0, 2**32 - 1)), draw(st.integers(0, 2**32 - 1))))
    elif kind == "garbage":
        data = draw(st.binary(max_size=300))
    else:
        data = b""
    if data and draw(st.booleans()):
        data = data[: draw(st.integers(0, len(data)))]
    if data and draw(st.booleans()):
        b = bytearray(data)
        b[draw(st.integers(0, len(b) - 1))] ^= draw(st.integers(1, 255))
        data = bytes(b)
    return SimpleNamespace(format=draw(st.sampled_from(["png", "jpeg", "", "16UC1; compressedDepth", "bmp"])),
                           data=data)


def check_output(out: object) -> None:
    """A stream result: None or a flow whose every derived array is finite."""
    if out is None:
        return
    assert np.isfinite(out.flow).all() and np.isfinite(out.magnitude).all()
    assert out.color().dtype == np.uint8 and np.isfinite([out.summary.mean, out.summary.max]).all()


@fuzz(150)
@given(st.lists(st.one_of(raw_images(), compressed_images()), min_size=1, max_size=4),
       st.lists(st.tuples(st.booleans(), st.integers(0, 10)), min_size=4, max_size=4))
def test_random_messages_through_codec_and_stream(msgs, stamps) -> None:
    stream = FlowStream(StreamSettings(config=small_frames.CONFIG))
    good = np.full((12, 16), 0.5, np.float32)
    good[4:8, 5:9] = 0.9
    stream.process(good, 0, "32FC1")
    for k, msg in enumerate(msgs):
        try:
            frame, label = decode(msg)
        except InputError as exc:
            assert str(exc) and "\n" not in str(exc)
            continue
        back, jump = stamps[k]
        try:
            check_output(stream.process(frame, (jump if back else 10 * k + 10 + jump), label))
        except InputError as exc:
            assert str(exc) and "\n" not in str(exc)


# ------------------------------------------------------------------------------------------------ bags
@lru_cache(maxsize=2)
def base_bag(storage: str) -> Path:
    """A tiny synthetic bag (4 frames of 32x24 with ground truth), made once per run."""
    folder = Path(tempfile.mkdtemp(prefix="fuzz_base_"))
    write_synth_bag(folder / "bag", SynthSpec(scene="translation", frames=4, size=(32, 24), seed=9,
                                              storage=storage))
    return folder / "bag"


EVAL_ARGS = small_frames.CLI_ARGS + ["-q", "--png-frames", "none"]


@st.composite
def bag_mutations(draw: st.DrawFn) -> tuple[str, list[tuple]]:
    """Storage and 1-2 mutations, mostly byte flips and truncations (the subtle ones)."""
    storage = draw(st.sampled_from(["mcap", "mcap", "sqlite3"]))
    ops = []
    for _ in range(draw(st.integers(1, 2))):
        kind = draw(st.sampled_from(["flip"] * 5 + ["truncate"] * 3 + ["metadata", "delete_storage"]))
        if kind == "flip":
            ops.append(("flip", draw(st.floats(0, 1)), draw(st.integers(1, 255))))
        elif kind == "truncate":
            ops.append(("truncate", draw(st.floats(0, 1))))
        elif kind == "metadata":
            ops.append(("metadata", draw(st.sampled_from(["delete", "garble", "truncate", "empty"]))))
        else:
            ops.append(("delete_storage",))
    return storage, ops


def mutate(bag: Path, ops: list[tuple], rng_bytes: bytes) -> None:
    store = next(p for p in bag.iterdir() if p.suffix in (".mcap", ".db3"))
    meta = bag / "metadata.yaml"
    for op in ops:
        if op[0] == "flip" and store.exists():
            b = bytearray(store.read_bytes())
            if b:
                b[min(int(op[1] * len(b)), len(b) - 1)] ^= op[2]
                store.write_bytes(bytes(b))
        elif op[0] == "truncate" and store.exists():
            store.write_bytes(store.read_bytes()[: int(op[1] * store.stat().st_size)])
        elif op[0] == "metadata" and meta.exists():
            text = meta.read_bytes()
            new = {"delete": None, "garble": rng_bytes, "truncate": text[: len(text) // 2], "empty": b""}[op[1]]
            meta.unlink() if new is None else meta.write_bytes(new)
        elif op[0] == "delete_storage" and store.exists():
            store.unlink()


def run_quiet(cli, argv: list[str]) -> tuple[int, str]:
    """Run a CLI main in-process; returns (exit code, stderr)."""
    err = io.StringIO()
    with redirect_stderr(err), redirect_stdout(io.StringIO()):
        try:
            rc = cli(argv)
        except SystemExit as exc:
            rc = exc.code
    return rc, err.getvalue()


def finite_flows(bag: Path) -> None:
    with Reader(bag) as r:
        conns = [c for c in r.connections if c.topic.startswith("/flow_node/")]
        from flow_node.bag.bagio import deserialize
        for c, _, raw in r.messages(connections=conns):
            assert np.isfinite(image_to_array(deserialize(raw, c.msgtype))).all()


def check_run(rc: int, err: str, prog: str, out: Path) -> None:
    """The invariants of one CLI run: no traceback; a failure is one error line and leaves neither the
    output nor a hidden partial one (the callers check that the line names what was wrong)."""
    assert "Traceback" not in err, err
    lines = err.strip().splitlines()
    if rc != 0:
        assert rc in (1, 2) and len(lines) == 1 and lines[0].startswith(f"{prog}: error: "), err
        assert not out.exists()
        assert not [p for p in out.parent.iterdir() if p.name.startswith(f".{out.name}") or ".tmp" in p.name]
    else:
        assert all(": warning: " in line for line in lines), err


@fuzz(40)
@given(bag_mutations(), st.binary(min_size=1, max_size=80))
def test_random_bag_mutations_through_eval(mutation, garbage) -> None:
    storage, ops = mutation
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(shutil.copytree(base_bag(storage), Path(tmp) / "bag"))
        mutate(bag, ops, garbage)
        out = Path(tmp) / "out"
        rc, err = run_quiet(flow_bag, ["eval", str(bag), "-o", str(out), *EVAL_ARGS])
        check_run(rc, err, "flow_bag eval", out)
        if rc == 1:
            assert str(bag) in err, err
        else:
            json.loads((out / "report.json").read_text(), parse_constant=lambda c: 1 / 0)
            finite_flows(out / "bag")


# ------------------------------------------------------------------------------------------------- CLI
@lru_cache(maxsize=1)
def cli_inputs() -> dict[str, str]:
    """A pool of inputs, good and bad, made once: name -> path."""
    d = Path(tempfile.mkdtemp(prefix="fuzz_cli_"))
    rng = np.random.default_rng(4)
    tex = (rng.random((24, 32)) * 255).astype(np.uint8)
    files = {"a.png": tex, "b.png": np.roll(tex, 1, 1), "c16.png": tex.astype(np.uint16) * 257,
             "small.png": tex[:8, :8], "rgb.png": np.dstack([tex] * 3)}
    for name, img in files.items():
        cv2.imwrite(str(d / name), img)
    huge = np.full((24, 32), 1e30, np.float32)
    cv2.imwrite(str(d / "huge.tiff"), huge)
    cv2.imwrite(str(d / "half.tiff"), tex.astype(np.float32) / 255)
    (d / "claim.png").write_bytes(_png(4, 4, (100000, 100000)))
    (d / "garbage.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\x00" * 50)
    (d / "empty.png").write_bytes(b"")
    (d / "dir").mkdir()
    (d / "ok.yaml").write_text("alpha: 15.0\n")
    (d / "ros.yaml").write_text("flow_node:\n  ros__parameters:\n    iterations: 5\n")
    (d / "bad.yaml").write_text("alpha: [1\n")
    (d / "latin.yaml").write_bytes("x: caf\xe9\n".encode("latin-1"))
    (d / "deep.yaml").write_text("x: " + "[" * 3000 + "]" * 3000 + "\n")
    (d / "list.yaml").write_text("- 1\n- 2\n")
    paths = {p.name: str(p) for p in d.iterdir()}
    paths.update({"missing": str(d / "missing.png"), "long": str(d / ("x" * 300 + ".png")), "devnull": os.devnull})
    return paths


IMAGES = ["a.png", "b.png", "c16.png", "small.png", "rgb.png", "huge.tiff", "half.tiff", "claim.png",
          "garbage.png", "empty.png", "dir", "missing", "long", "devnull", "ok.yaml"]
KEYS = ["alpha", "iterations", "model", "levels", "scale_factor", "warps", "backend", "nope", ""]
JUNK = st.one_of(st.sampled_from(["", "x", "inf", "nan", "-1", "1e30", "true"]), st.text(max_size=6))
NUMBERS = st.one_of(st.sampled_from(["0", "1", "5", "-1", "inf", "nan", "1e30", "0.5"]),
                    st.floats(-1e3, 1e3).map(repr))
OPTION_VALUES = {"--max-flow": st.one_of(NUMBERS, JUNK), "--model": st.sampled_from(list(MODELS) + ["l9", ""]),
                 "--preset": st.sampled_from(["realtime", "balanced", "quality", "fast", ""])}


@st.composite
def estimate_argv(draw: st.DrawFn) -> tuple[list[str], str, str]:
    """(argv without --output, colour file name or "", output kind); mostly valid, one thing wrong at a time
    in about half the cases."""
    pool = cli_inputs()
    bad_input = draw(st.integers(0, 3)) == 0
    f0 = draw(st.sampled_from(IMAGES if bad_input else ["a.png", "c16.png", "rgb.png", "half.tiff"]))
    f1 = draw(st.sampled_from(["b.png"] * 6 + ["a.png", "small.png", "huge.tiff", "claim.png"]))
    argv = [pool[f0], pool[f1], *small_frames.CLI_ARGS]
    for _ in range(draw(st.integers(0, 2))):
        opt = draw(st.sampled_from(["--set", "--set", "--max-flow", "--params", "--model", "--preset", "--bogus"]))
        if opt == "--set":
            key = draw(st.sampled_from(KEYS))
            argv += ["--set", f"{key}={draw(NUMBERS if key in KEYS[:6] else JUNK)}"]
        elif opt == "--params":
            argv += ["--params", pool[draw(st.sampled_from(["ok.yaml", "ros.yaml", "ok.yaml", "bad.yaml", "latin.yaml",
                                                             "deep.yaml", "list.yaml", "dir", "missing"]))]]
        elif opt == "--bogus":
            argv += ["--bogus"]
        else:
            argv += [opt, draw(OPTION_VALUES[opt])]
    output = draw(st.sampled_from(["ok"] * 6 + ["dir", "missing_dir", "full", "long"]))
    color = draw(st.sampled_from(["", "", "", "c.png", "c.png", "c.jpg", "c.xyz", "noext", "cdir"]))
    return argv, color, output


@fuzz(60)
@given(estimate_argv())
def test_random_flow_estimate_invocations(case) -> None:
    argv, color, output = case
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        (d / "cdir").mkdir()
        out = {"ok": d / "o.flo", "dir": d / "cdir", "missing_dir": d / "no" / "o.flo", "full": Path("/dev/full"),
               "long": d / ("y" * 300 + ".flo")}[output]
        argv = argv + ["--output", str(out)] + (["--color", str(d / color)] if color else [])
        rc, err = run_quiet(flow_estimate, argv)
        assert "Traceback" not in err, err
        lines = err.strip().splitlines()
        if rc != 0:
            assert rc in (1, 2) and len(lines) == 1 and lines[0].startswith("flow_estimate: error: "), err
            assert len(lines[0]) <= 420
            assert sorted(p.name for p in d.iterdir()) == ["cdir"]  # nothing written, no temporary left
            assert not any((d / "cdir").iterdir())
        else:
            assert err == "" and output == "ok"
            assert np.isfinite(read_flo(out)).all()
            if color:
                assert (d / color).is_file()


def test_fuzz_bag_helper_writes_valid_bags(tmp_path) -> None:
    """The mutation fuzzer's base bags evaluate cleanly (else every mutation would only test errors)."""
    for storage in ("mcap", "sqlite3"):
        out = tmp_path / storage
        rc, err = run_quiet(flow_bag, ["eval", str(base_bag(storage)), "-o", str(out), *EVAL_ARGS])
        assert rc == 0 and err == "", err
        report = json.loads((out / "report.json").read_text())
        assert report["models"][0]["summary"]["pairs_with_gt"] == 3
    with BagWriter(tmp_path / "w", "mcap") as w:  # and a hand-made one goes through the same writer
        w.add_topic("/x", IMAGE)
        w.write("/x", 1, image_message(header(1, "c"), array_to_image_fields(np.zeros((2, 2), np.uint8), "mono8")))


@st.composite
def eval_argv(draw: st.DrawFn) -> list[str]:
    """flow_bag eval options, mostly valid, some not."""
    argv: list[str] = []
    for _ in range(draw(st.integers(0, 3))):
        opt = draw(st.sampled_from(["--max-flow", "--png-frames", "--model", "--set", "--image-topic", "--gt-topic"]))
        if opt == "--max-flow":
            argv += [opt, draw(st.one_of(NUMBERS, JUNK))]
        elif opt == "--png-frames":
            argv += [opt, draw(st.sampled_from(["auto", "all", "none", "1,2", "0", "99", "x", "1,,2", "-1"]))]
        elif opt == "--model":
            argv += [opt, ",".join(draw(st.lists(st.sampled_from(list(MODELS) + ["l9", ""]), min_size=1,
                                                 max_size=3)))]
        elif opt == "--set":
            key = draw(st.sampled_from(KEYS))
            argv += [opt, f"{key}={draw(NUMBERS if key in KEYS[:6] else JUNK)}"]
        else:
            argv += [opt, draw(st.sampled_from(["/camera/image_raw", "/camera/flow_gt", "/nope", ""]))]
    return argv


@fuzz(30)
@given(eval_argv())
def test_random_flow_bag_eval_arguments(extra) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        rc, err = run_quiet(flow_bag, ["eval", str(base_bag("mcap")), "-o", str(out), *EVAL_ARGS, *extra])
        check_run(rc, err, "flow_bag eval", out)
        if rc == 0:
            report = json.loads((out / "report.json").read_text(), parse_constant=lambda c: 1 / 0)
            chosen = [extra[k + 1] for k, a in enumerate(extra) if a == "--image-topic"]
            assert report["images"] == (3 if chosen[-1:] == ["/camera/flow_gt"] else 4)  # 3 flows, 4 frames
            finite_flows(out / "bag")
