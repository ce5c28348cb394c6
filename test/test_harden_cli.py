"""flow_estimate and flow_bag eval on hostile invocations (issue 15, items 1 and 3-8): each failure is one
line on stderr naming the input, exit 1 (2 for usage), no traceback, and no output left behind; native
library warnings never reach stderr. Run in-process with ``capfd``, so anything written to file descriptor 2
(libpng's own warnings included) is seen."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
import small_frames
from synth import constant_flow, pair_from_flow, texture
from test_harden_frames import png_claiming

from flow_node.bag.cli import main as flow_bag
from flow_node.cli.estimate import main as flow_estimate
from flow_node.core.flowio import read_flo

BAGS = Path(__file__).resolve().parent.parent / "bags"
FAST = small_frames.CLI_ARGS


@pytest.fixture
def pair(tmp_path: Path) -> tuple[Path, Path]:
    i0, i1 = pair_from_flow(texture(40, 48, seed=5), constant_flow(40, 48, 1.0, 0.5))
    paths = tmp_path / "f0.png", tmp_path / "f1.png"
    for p, img in zip(paths, (i0, i1), strict=True):
        cv2.imwrite(str(p), (np.clip(img, 0, 1) * 255).round().astype(np.uint8))
    return paths


def fails(capfd: pytest.CaptureFixture[str], argv: list[str], code: int = 1, cli=flow_estimate) -> str:
    """Run ``cli`` expecting exit ``code``; return its single stderr line (checked: one line, no traceback)."""
    try:
        rc = cli(argv)
    except SystemExit as exc:  # argparse usage errors
        rc = exc.code
    out, err = capfd.readouterr()
    lines = err.strip().splitlines()
    assert rc == code, err
    assert len(lines) == 1 and "Traceback" not in err and len(lines[0]) <= 420, err[:2000]
    return lines[0]


def no_outputs(folder: Path, *keep: str) -> None:
    """Nothing in ``folder`` besides the inputs ``keep`` (no .flo, no colour image, no temporary file)."""
    left = sorted(p.name for p in folder.iterdir() if p.name not in keep)
    assert left == [], left


def test_float_tiff_of_huge_values_is_rejected_and_nothing_written(tmp_path, capfd, pair) -> None:
    tif = tmp_path / "huge.tiff"
    f = np.full((40, 48), 1e30, np.float32)
    f[::2] = 0.5
    assert cv2.imwrite(str(tif), f)
    line = fails(capfd, [str(tif), str(pair[1]), "-o", str(tmp_path / "o.flo"), *FAST])
    assert "huge.tiff" in line and "float values reach 1e+30" in line
    no_outputs(tmp_path, "f0.png", "f1.png", "huge.tiff")


def test_png_claiming_a_huge_size_is_one_line(tmp_path, capfd, pair) -> None:
    big = tmp_path / "big.png"
    big.write_bytes(png_claiming(100000, 100000))
    line = fails(capfd, [str(big), str(pair[1]), "-o", str(tmp_path / "o.flo"), *FAST])
    assert "big.png is 100000x100000 px, over the limit" in line
    no_outputs(tmp_path, "f0.png", "f1.png", "big.png")


@pytest.mark.parametrize("color,expect", [("c.xyz", "no image writer for extension '.xyz'"),
                                          ("cdir", "cdir: Is a directory"),
                                          ("missing/c.png", "missing/c.png: No such file or directory"),
                                          ("noext", "no image writer for extension '(none)'")])
def test_bad_colour_path_fails_before_anything_is_written(tmp_path, capfd, pair, color, expect) -> None:
    (tmp_path / "cdir").mkdir()
    old = tmp_path / "o.flo"
    old.write_bytes(b"previous result")
    line = fails(capfd, [*map(str, pair), "-o", str(old), "--color", str(tmp_path / color), *FAST])
    assert expect in line, line
    assert old.read_bytes() == b"previous result"  # an existing output is replaced only on success
    no_outputs(tmp_path, "f0.png", "f1.png", "o.flo", "cdir")


def test_success_writes_both_and_leaves_no_temporary(tmp_path, capfd, pair) -> None:
    assert flow_estimate([*map(str, pair), "-o", str(tmp_path / "o.flo"), "--color", str(tmp_path / "c.png"),
                          *FAST]) == 0
    flow = read_flo(tmp_path / "o.flo")
    assert np.isfinite(flow).all() and abs(float(np.median(flow[..., 0])) - 1.0) < 0.2
    assert cv2.imread(str(tmp_path / "c.png")).shape == (40, 48, 3)
    no_outputs(tmp_path, "f0.png", "f1.png", "o.flo", "c.png")
    assert capfd.readouterr().err == ""


def with_bad_text_chunk(png: bytes) -> bytes:
    """``png`` with a tEXt chunk whose CRC is wrong: libpng warns on fd 2 ("tEXt: CRC error") and decodes."""
    text = b"Comment\0hello"
    return png[:33] + len(text).to_bytes(4, "big") + b"tEXt" + text + b"\xde\xad\xbe\xef" + png[33:]


def test_libpng_warnings_never_reach_stderr(tmp_path, capfd, pair) -> None:
    warn = tmp_path / "warn.png"
    warn.write_bytes(with_bad_text_chunk(pair[0].read_bytes()))
    assert cv2.imread(str(warn)) is not None
    assert "libpng warning" in capfd.readouterr().err  # what OpenCV alone lets through
    assert flow_estimate([str(warn), str(pair[1]), "-o", str(tmp_path / "o.flo"), *FAST]) == 0
    assert capfd.readouterr().err == ""
    # a real process (stderr is fd 2 itself): the error is the only line
    small = tmp_path / "small.png"
    small.write_bytes(with_bad_text_chunk(cv2.imencode(".png", np.zeros((8, 8), np.uint8))[1].tobytes()))
    proc = subprocess.run([sys.executable, "-m", "flow_node.cli.estimate", str(warn), str(small), "-o",
                           str(tmp_path / "x.flo"), *FAST], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1 and proc.stderr.splitlines() == [
        "flow_estimate: error: frames differ in size: frame0 is 48x40, frame1 is 8x8"], proc.stderr


def test_eval_of_pngs_libpng_warns_about_is_silent(tmp_path, capfd) -> None:
    from test_harden_bags import scene, write

    frames, gts = scene(3)
    pngs = [("png", with_bad_text_chunk(cv2.imencode(".png", f)[1].tobytes())) for f in frames]
    bag = write(tmp_path / "bag", pngs, gts)
    assert flow_bag(["eval", str(bag), "-o", str(tmp_path / "out"), *FAST, "-q"]) == 0
    assert capfd.readouterr().err == ""


def test_input_kinds_have_their_own_message(tmp_path, capfd, pair) -> None:
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    (tmp_path / "empty.png").write_bytes(b"")
    cases = [(tmp_path, "is a directory"), (fifo, "is a FIFO"), ("/dev/null", "is a character device"),
             (tmp_path / "empty.png", "the file is empty"), (tmp_path / "nope.png", "no such file"),
             ("x" * 5000 + ".png", "File name too long")]
    for path, expect in cases:
        line = fails(capfd, [str(path), str(pair[1]), "-o", str(tmp_path / "o.flo"), *FAST])
        assert expect in line and line.count("cannot read") == 1, line
    assert not (tmp_path / "o.flo").exists()


def test_full_disk_and_directory_outputs(tmp_path, capfd, pair) -> None:
    line = fails(capfd, [*map(str, pair), "-o", "/dev/full", *FAST])
    assert line == "flow_estimate: error: cannot write /dev/full: No space left on device"
    line = fails(capfd, [*map(str, pair), "-o", str(tmp_path), *FAST])
    assert line.endswith(f"cannot write {tmp_path}: Is a directory")
    line = fails(capfd, [*map(str, pair), "-o", str(tmp_path / ("y" * 300 + ".flo")), *FAST])
    assert "File name too long" in line
    no_outputs(tmp_path, "f0.png", "f1.png")


@pytest.mark.parametrize("value", ["inf", "nan", "-1", "-inf", "abc"])
def test_max_flow_must_be_finite_and_not_negative(tmp_path, capfd, pair, value) -> None:
    line = fails(capfd, [*map(str, pair), "-o", str(tmp_path / "o.flo"), f"--max-flow={value}"], code=2)
    assert "--max-flow" in line and repr(value) in line
    line = fails(capfd, ["eval", str(BAGS / "objects"), "-o", str(tmp_path / "ev"), f"--max-flow={value}"],
                 code=2, cli=flow_bag)
    assert "--max-flow" in line
    no_outputs(tmp_path, "f0.png", "f1.png")


PARAMS = {
    "latin1.yaml": ("alpha: 1.0  # caf\xe9\n".encode("latin-1"), "not UTF-8 text (byte 0xe9"),
    "deep.yaml": (b"alpha: " + b"[" * 5000 + b"]" * 5000 + b"\n", "nested"),
    "blockdeep.yaml": (b"a:\n" + b"- " * 200000 + b"x\n", "nested"),  # libyaml's C loader segfaults here
    "deep16.yaml": (b"a: " + b"[" * 40 + b"]" * 40 + b"\n", "nested deeper than 16 levels"),
    "invalid.yaml": (b"alpha: 1\n  beta: [2\n", "is not valid YAML: "),
    "laughs.yaml": (b"a: &a [x, x, x, x, x, x, x, x, x]\n" + b"".join(
        f"{c}: &{c} [{', '.join(['*' + p] * 9)}]\n".encode() for p, c in zip("abcdefgh", "bcdefghi", strict=True)),
        "more than 100000 values"),
}


@pytest.mark.parametrize("name", sorted(PARAMS))
def test_bad_params_files_are_one_line_in_both_tools(tmp_path, capfd, pair, name) -> None:
    data, expect = PARAMS[name]
    params = tmp_path / name
    params.write_bytes(data)
    line = fails(capfd, [*map(str, pair), "-o", str(tmp_path / "o.flo"), "--params", str(params)])
    assert expect in line and name in line, line
    line = fails(capfd, ["eval", str(BAGS / "objects"), "-o", str(tmp_path / "ev"), "--params", str(params),
                         "-q"], cli=flow_bag)
    assert expect in line and name in line, line
    no_outputs(tmp_path, "f0.png", "f1.png", name)


def test_params_that_are_a_directory_or_fifo(tmp_path, capfd, pair) -> None:
    fifo = tmp_path / "fifo.yaml"
    os.mkfifo(fifo)
    for p in (tmp_path, fifo):
        line = fails(capfd, [*map(str, pair), "-o", str(tmp_path / "o.flo"), "--params", str(p)])
        assert "not a regular file" in line


def test_symlinked_output_is_written_through(tmp_path, capfd, pair) -> None:
    target = tmp_path / "real.flo"
    target.write_bytes(b"old")
    link = tmp_path / "link.flo"
    link.symlink_to(target)
    assert flow_estimate([*map(str, pair), "-o", str(link), *FAST]) == 0
    assert link.is_symlink() and read_flo(target).shape == (40, 48, 2)
    no_outputs(tmp_path, "f0.png", "f1.png", "real.flo", "link.flo")


def test_synth_refuses_a_size_it_cannot_render(tmp_path, capfd) -> None:
    line = fails(capfd, ["synth", str(tmp_path / "b"), "--size", "100000x100000"], cli=flow_bag)
    assert "size must be from 8x8 to 4096x4096, got 100000x100000" in line
    assert not any(tmp_path.iterdir())
