"""The suite's regimes: a name, a one-line title, and how to build its samples for a split.

Recorded data (Middlebury, large motions, bags) is the same in every split; the synthetic regimes draw
their seeds from the split (see :mod:`.synthetic`), the photometric regimes their families of changes (see
:mod:`.photometric`), and ``real_exact`` its photographs and shifts (see :mod:`.realexact`).

The ``stream`` regime is not here: its methods carry state from frame to frame, so it has its own runner over
whole sequences (:mod:`.streams`, :mod:`.sequences`; docs/suite.md, "Streams").
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

from . import data, mass, missing, photometric, realexact, synthetic
from .data import Sample


@dataclass(frozen=True)
class Regime:
    """``build(split, quick)`` returns the samples; ``seeded`` regimes depend on the split; ``exclude`` names
    methods not run on it (with the reason in the title)."""

    name: str
    title: str
    build: Callable[[str, bool], Iterable[Sample]]
    seeded: bool = True
    report_only: bool = False
    exclude: tuple[str, ...] = ()


REGIMES: dict[str, Regime] = {r.name: r for r in (
    Regime("middlebury", "Middlebury training set (real; frame10 -> frame11)", lambda split, q: data.middlebury(q),
           seeded=False),
    Regime("large", "Large motions (../shared/data/large, 20-250 px; report only; without DualTVL1, which "
           "takes 25-140 s per pair on them)", lambda split, q: data.large(q), seeded=False, report_only=True,
           exclude=("dualtvl1",)),
    Regime("fine_320", "Fine band-limited textures, 320x240, 8 bit, shifts/rotations/zooms/affine 0.3-3 px",
           lambda split, q: synthetic.fine(split, q, (320, 240))),
    Regime("fine_640", "Fine band-limited textures, 640x480, 8 bit, shifts/rotations/zooms/affine 0.3-3 px",
           lambda split, q: synthetic.fine(split, q, (640, 480))),
    Regime("bit_depth", "Fine textures 320x240 delivered at 8, 10, 12, 16 bit (mono16 up to 2^bits - 1)",
           synthetic.bit_depth),
    Regime("noise", "Fine textures 320x240 with sensor noise sigma 1-3 grey levels", synthetic.noise),
    Regime("missing", "Fine textures 320x240 with pixels carrying garbage (the robot's body and lens dirt, a wiper, "
           "stuck pixels), ground truth everywhere; '<preset>+mask' methods are given the masks",
           missing.missing),
    Regime("exposure", "Fine textures 320x240, frame 2 with gain 0.75-1.33 and an offset", synthetic.exposure),
    Regime("low_contrast", "Fine textures 320x240 spanning 24 or 10 grey levels", synthetic.low_contrast),
    Regime("flat", "Fine textures 320x240 with ~half the area flat", synthetic.flat_areas),
    Regime("photometric", "Fine textures 320x240 (grey 0.04-0.96), frame 2 under the split's photometric families "
           "(tune: gamma, vignetting, clipping, sensor noise; report: S-curve, log/knee, illumination, flicker, "
           "white balance (RGB), low light)", photometric.synthetic_photometric),
    Regime("photometric_real", "Middlebury pairs, frame 2 under the split's photometric families (images the same "
           "in every split; without DualTVL1, which takes 10-30 s per pair on them)",
           photometric.middlebury_photometric, exclude=("dualtvl1",)),
    Regime("real_exact", "Real photographs moved by integer shifts and block-averaged by 2-4 (exact sub-pixel "
           "flow), with a foreground cut from another photograph; grey and RGB", realexact.real_exact),
    Regime("real_exact_photometric", "The real_exact pairs, frame 2 under the split's photometric families",
           realexact.real_exact_photometric),
    Regime("mass", "Density textures 320x240 moved by compressible maps (affine zoom/shear with det != 1, radial "
           "sources/sinks, separable sinusoids), frame 2's intensity scaled by 1/det of the map: mass preserved, "
           "brightness not (report only for the presets and peers, all brightness-constancy models; the mass "
           "target compares the methods named 'brightness' and 'mass')", mass.mass, report_only=True),
    Regime("bags", "The bundled bags (128x96; mono8, mono16, rgb8, png; noise and brightness in 'objects')",
           lambda split, q: data.bags(q), seeded=False),
)}
