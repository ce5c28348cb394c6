"""The ``real_exact`` regime's construction is exact (bench/suite/realexact.py, docs/suite.md "Real photographs
moved exactly"): for every pair of both splits, grey and RGB, frame 1 at full resolution read at p + f gt(p)
equals frame 0 read straight off the photographs at every known, non-occluded block (max error 0, and 0 for
the block means before quantisation), and the delivered frames are the 8-bit quantisation of the block means.
A change to the generator that interpolates, shifts by a multiple of f or mislabels a block fails here."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from bench.suite import realexact as rx
from bench.suite.data import Sample
from bench.suite.synthetic import quantise


def spec_of(name: str) -> rx.Spec:
    """The spec whose name begins the sample's name (a sample is 'NAME' or 'NAME_rgb')."""
    for split, table in rx.SPLIT_PAIRS.items():
        for k in range(len(table)):
            spec = rx.make_spec(split, k)
            if name == spec.name or name.startswith(spec.name + "_"):
                return spec
    raise ValueError(f"{name!r} is not a real_exact sample")


def source_frame0(spec: rx.Spec, colour: bool) -> np.ndarray:
    """Frame 0 at full resolution read straight off the photographs (not through rx.compose): the
    background's window, and the foreground at its offset inside the mask."""
    a, b = rx.photograph(spec.background), rx.photograph(spec.foreground)
    if not colour:
        a, b = rx.grey(a), rx.grey(b)
    x0, y0, cw, ch = spec.window
    ys, xs = np.mgrid[0:ch, 0:cw]
    fy, fx = np.clip(ys + spec.fg_offset[1], 0, b.shape[0] - 1), np.clip(xs + spec.fg_offset[0], 0, b.shape[1] - 1)
    m = spec.mask[..., None] if colour else spec.mask
    return np.where(m, b[fy, fx], a[y0 + ys, x0 + xs])


def check_pair(sample: Sample) -> dict[str, float]:
    """The sample against its construction: ``err_full`` (full resolution) and ``err_block`` (block means)
    max |I1(p + f gt) - I0(p)| over the known, not occluded blocks, ``quantised`` 1 if the frames are the
    8-bit block means, ``known`` / ``occluded`` fractions of the output pixels. Raises if f gt is not an
    integer off the multiples of f (float32 holds s / 3 to ~1e-7 px)."""
    spec, colour = spec_of(sample.name), sample.f0.ndim == 3
    f = spec.factor
    src0, full1 = source_frame0(spec, colour), rx.compose(spec, 1, colour)[0]
    known = np.all(np.abs(sample.gt) < 1e9, axis=-1)
    ok = known & ~sample.occluded if sample.occluded is not None else known
    disp = np.rint(sample.gt[ok] * f).astype(int)
    assert np.max(np.abs(disp - sample.gt[ok].astype(np.float64) * f)) <= 1e-5, "f * gt is not an integer"
    assert not np.any(disp % f == 0), "a shift is a multiple of f"
    pad = rx.MAX_SHIFT + 1
    big = np.pad(full1, ((pad, pad), (pad, pad)) + ((0, 0),) * (full1.ndim - 2), constant_values=np.nan)
    err_full = err_block = 0.0
    for d in {tuple(v) for v in disp}:
        sel = ok & np.all(np.rint(sample.gt * f) == d, axis=-1)
        warped = big[pad + d[1]:pad + d[1] + full1.shape[0], pad + d[0]:pad + d[0] + full1.shape[1]]
        px = np.kron(sel, np.ones((f, f), bool))
        err_full = max(err_full, float(np.max(np.abs(warped[px] - src0[px]))))
        err_block = max(err_block, float(np.max(np.abs(rx.block_mean(warped, f)[sel] - rx.block_mean(src0, f)[sel]))))
    same = (np.array_equal(sample.f0, quantise(rx.block_mean(src0, f), 8))
            and np.array_equal(sample.f1, quantise(rx.block_mean(full1, f), 8)))
    return {"err_full": err_full, "err_block": err_block, "quantised": float(same),
            "known": float(known.mean()), "occluded": float((known & ~ok).mean())}


@pytest.mark.parametrize("split", ["tune", "report"])
def test_every_real_exact_pair_is_exact(split: str) -> None:
    samples = list(rx.real_exact(split, quick=False))
    assert len(samples) >= len(rx.SPLIT_PAIRS[split])
    for sample in samples:
        r = check_pair(sample)
        assert r["err_full"] == 0.0 and r["err_block"] == 0.0, (sample.name, r)
        assert r["quantised"] == 1.0, sample.name
        assert 0.98 <= r["known"] <= 1.0 and r["occluded"] < 0.5, (sample.name, r)


def test_the_check_sees_a_wrong_flow() -> None:
    """The check itself fails when the truth is off by one output pixel (not a vacuous check)."""
    sample = next(rx.real_exact("tune", quick=True))
    known = np.abs(sample.gt) < 1e9
    r = check_pair(replace(sample, gt=np.where(known, sample.gt + 1.0, sample.gt).astype(np.float32)))
    assert r["err_full"] > 0.0 and r["err_block"] > 0.0
