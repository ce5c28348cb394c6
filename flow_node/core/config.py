"""The one typed configuration object of the engine, its validation, presets and YAML loading (the file itself
is read by params_file.py).

Every entry point (Python API, ``flow_estimate``, the ROS node's parameters, ``flow_bag``) maps onto
:class:`FlowConfig`; defaults, ranges and descriptions live only here (in each field's metadata), so the node
builds its parameter descriptors and the CLI its help from the same table.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

from .census import CENSUS
from .colour import COLOUR_MODES
from .errors import ConfigError
from .initialise import SOURCES as INITIALISATIONS
from .models import CONSTRAINTS, MODEL_SPECS
from .params_file import read_mapping, ros_parameters
from .photometric import MASS_PHOTOMETRIC, PHOTOMETRIC, RELIABILITY_SAMPLES
from .presets import PRESETS
from .settings import FieldInfo
from .settings import check_field as _check_field
from .settings import fields_info as settings_fields_info
from .settings import setting as _f
from .warping import KERNELS as WARP_KERNELS

# The choices of the fields below come from the modules that implement them (one table each): the models'
# names from MODEL_SPECS, the initialisations from initialise.py, the photometric modes and warp kernels from
# theirs.
MODELS: tuple[str, ...] = tuple(MODEL_SPECS)
TV_NORMS = ("isotropic", "anisotropic")
GRADIENT_SCHEMES = ("forward", "central", "interpolated")
BACKENDS = ("auto", "numpy", "numba")
RECONSTRUCTIONS = ("none", "joint")  # images the flow is solved on: the measured ones, or the joint model's (joint.py)


class _Calibrated(float):
    """The default of alpha/alpha1: a marker (not a value a user can pass) replaced on construction by the
    model's calibrated weight (MODEL_WEIGHTS)."""


CALIBRATED = _Calibrated("nan")


@dataclass(frozen=True)
class FlowConfig:
    """All settings of the flow engine. Construct, ``replace`` or load; every path validates.

    Weights refer to grey images scaled to [0, 1] and flow in pixels per frame. The energy minimised on
    each warp is ``D(v) + alpha * R(v)`` (paper, "Models"); for the extended models
    ``R(v, w) = ||grad v - w||_1 + (alpha1 / alpha) * S(w)`` i.e. ``alpha`` is the paper's alpha_0 and
    ``alpha1`` its alpha_1, both absolute.
    """

    photometric: str = _f("normalise", "what the data term compares: census (each pixel's soft census signature, its "
                          "3x3 differences over their local contrast: invariant to tone curves, gain fields and "
                          "flicker), normalise (grey values on the pair's 2nd-98th percentile range; an exposure "
                          "change is detected and undone), local_contrast, structure_texture (grey values after "
                          "local normalisation / Wedel's texture part), density (one gain, nothing subtracted: keeps "
                          "mass, for constraint=mass), none (grey / max)",
                          choices=PHOTOMETRIC)
    colour: str = _f("grey", "what the data term sees of colour input: grey (the BT.601 luma) or channels (with "
                     "photometric census: the signatures of R, G and B, each channel normalised on its own, "
                     "stacked into one data term; invariant to white balance; ~1.9x the census term's time, "
                     "docs/engine.md). Grey input, and the grey-value data terms, use the luma either way",
                     choices=COLOUR_MODES)
    census_antialias: int = _f(-1, "photometric census at full resolution (finest_level 0): how many of the finest "
                               "pyramid steps are anti-aliased (the coarser ones get the weak blur of the grey-value "
                               "modes; -1 = every step). The strong blur on every step spreads a smooth scene's edges "
                               "over flat areas, whose signature then moves with them; quality and realtime set 3 "
                               "(chosen on the suite's tune split, docs/engine.md 'Presets')", lo=-1, hi=30)
    census_eps: float = _f(CENSUS.eps, "photometric census: the signature's EPS (of the frame's robust range) on the "
                           "levels census_coarse_eps does not damp: neighbour differences below it are damped, not "
                           "normalised (still invariant). A smaller EPS makes faint texture count (a stronger data "
                           "term on real photographs) and faint noise or remnants too (issue 25, task feps, "
                           "docs/engine.md 'Presets')", lo=0.0, hi=1.0, lo_open=True)
    census_coarse_eps: float = _f(0.01, "photometric census: the signature's EPS (of the frame's robust range) on "
                                  "pyramid levels narrower than census_coarse_width (still invariant: EPS only damps "
                                  "flat areas; the finer levels' EPS is census_eps; quality, realtime and fastest set "
                                  "0.03)",
                                  lo=0.0, hi=1.0, lo_open=True)
    census_coarse_width: int = _f(0, "photometric census: levels narrower than this (px) use census_coarse_eps "
                                  "(0 = none; quality, realtime and fastest set 50: for quality and realtime the "
                                  "contrast rule alone, census_empty_contrast, was worse on the tune split, "
                                  "docs/engine.md 'Presets')",
                                  lo=0, hi=100000)
    census_empty_contrast: float = _f(0.0, "photometric census: a pyramid level whose median 3x3 contrast (RMS of the "
                                      "neighbour differences, of the frame's robust range; the larger of the two "
                                      "frames': empty in both) is below this is empty -- the anti-alias blur took its "
                                      "texture -- and uses census_coarse_eps: undamped, its signature is whatever "
                                      "faint remnant or illumination is left (0 = off; fastest sets 0.005, realtime "
                                      "0.002, both beside the width rule, chosen on the suite's tune split; both "
                                      "frames since task crush; docs/engine.md 'Presets')",
                                      lo=0.0, hi=1.0)
    census_noise_k: float = _f(3.0, "photometric census: the signature's EPS is at least this many times the pair's "
                               "noise std (estimated once per frame at full resolution, the larger of the two, "
                               "used in both frames, carried down the pyramid by its filters' noise gain; 0 = "
                               "off). Damps flat areas whose contrast is noise (low light); 3 chosen on the suite's "
                               "tune split (2 before task noisek; docs/engine.md, 'The census data term')",
                               lo=0.0, hi=100.0)
    census_finest_radius: int = _f(1, "photometric census: the distance (px) of the signature's eight neighbours "
                                   "on the finest solved level: 1 = the 3 x 3 neighbourhood, as on every coarser "
                                   "level; 2 = the ring at distance 2 (the 5 x 5 window's corners and edge "
                                   "midpoints), which sees more of a smooth texture's curvature; quality and realtime "
                                   "set 2 (issue 25, eleventh and twelfth rounds; docs/engine.md, 'The census data "
                                   "term')", choices=(1, 2))
    census_median_filter: int = _f(-1, "photometric census: median filter size after each warp of a level but its "
                                   "last (-1 = median_filter; the last warp's is median_filter's). The earlier "
                                   "medians only move the next warp's linearisation point, and a 3 x 3 median costs "
                                   "~1/7 of a 5 x 5: fastest sets 3 (issue 25's time round, chosen on the suite's "
                                   "tune split, docs/engine.md)", choices=(-1, 0, 3, 5))
    census_iterations: int = _f(0, "photometric census: primal-dual iterations per warp (0 = iterations; quality sets "
                                "8: issue 25's time round, docs/engine.md)", lo=0, hi=100000)
    census_finest_iterations: int = _f(0, "photometric census: primal-dual iterations per warp on the finest solved "
                                       "level (0 = finest_iterations, else census_iterations or iterations; realtime "
                                       "sets 28 beside census_finest_warps 1: issue 25, task cschedule, "
                                       "docs/engine.md)", lo=0, hi=100000)
    census_finest_warps: int = _f(0, "photometric census: warps on the finest solved level (0 = finest_warps, else "
                                  "warps). Each costs the census kernel once at that level's size: realtime sets 1 "
                                  "(x 28 iterations), 2 x 16 took ~1.2x its time (issue 25, task cschedule, "
                                  "docs/engine.md 'Presets')",
                                  lo=0, hi=100)
    census_alpha: float = _f(0.0, "photometric census: the regularisation weight alpha with the census data term "
                             "(0 = alpha); realtime sets 0.10 beside census_delta 0.07, quality 0.10 beside 0.05, "
                             "fastest 0.35 beside 0.02: the smaller quadratic zone makes the term pull harder (issue "
                             "25, tasks smoothbags, qdelta, fastdelta and fastbags, docs/engine.md 'Presets')",
                             lo=0.0, hi=1000.0)
    census_delta: float = _f(CENSUS.delta, "photometric census: the residual (signature units) below which the L1 "
                             "term's majoriser is quadratic (its weight 1/sqrt(rho^2 + delta^2) flat). A quadratic "
                             "data term pulls less than TV near the solution and shrinks a flow's gradient (rotation, "
                             "zoom, deformation; realtime sets 0.07, quality 0.05, fastest 0.02: issue 25, tasks "
                             "smoothbags, qdelta, fastdelta and fastbags, docs/engine.md 'Presets')",
                             lo=0.0, hi=10.0, lo_open=True)
    census_presmooth: float = _f(0.0, "photometric census: presmooth both frames of every pair by a Gaussian of this "
                                 "many px (each colour channel alike), whatever their quantisation, also at half "
                                 "size on top of the anti-alias blur; coarsely quantised pairs keep at least the 1 px "
                                 "they get anyway (0 = only those: the comparison then depends on the encoding, 8-bit "
                                 "low range against 10-16 bit). realtime sets 0.45 (task presm, docs/engine.md 'The "
                                 "census data term')", lo=0.0, hi=5.0)
    constraint: str = _f("brightness", "what the data term asks of the motion: brightness (constancy, "
                         "I1(x + v) = I0(x)) or mass (preservation, the continuity equation I_t + div(I v) = 0: "
                         "densities that thin out or pile up, e.g. fluids, cells, PET; needs photometric density "
                         "or none, which setting mass without photometric selects)", choices=CONSTRAINTS)
    mass_brightness: float = _f(0.1, "constraint mass only: weight beta of a brightness-constancy term beside the "
                                "mass term (the model's data penalty on g I1(x + v) - I0(x), g the gain to equal "
                                "mass, times beta; 0 = the pure continuity equation), on pyramid levels of at least "
                                "60 px. Both agree where div v = 0 and it holds the border band of rotations; it "
                                "biases compressible flows by beta (0.1 chosen on the tune split; docs/engine.md, "
                                "'Mass preservation')", lo=0.0, hi=100.0)
    model: str = _f("l1_tv", "variational model: data term and regulariser (paper, Table 1); choosing a "
                    "model without alpha/alpha1 also selects its calibrated weights", choices=MODELS)
    alpha: float = _f(CALIBRATED, "regularisation weight alpha (alpha_0 for l1_tv_l2/l1_tv_tv); default: the "
                      "model's calibrated weight", lo=0.0, hi=1000.0, lo_open=True)
    alpha1: float = _f(CALIBRATED, "second weight alpha_1: of (1/2)|w|^2 in l1_tv_l2, of |grad w|_1 in l1_tv_tv; "
                       "default: the model's calibrated weight", lo=0.0, hi=10000.0)
    tv_norm: str = _f("isotropic", "vector norm of the TV terms: isotropic (joint Euclidean) or "
                      "anisotropic (sum of absolute values)", choices=TV_NORMS)
    gradient_scheme: str = _f("central", "image gradient: forward, central, or interpolated "
                              "(central on the mean of frame 0 and warped frame 1)",
                              choices=GRADIENT_SCHEMES)
    bregman_iterations: int = _f(0, "contrast-restoring Bregman iterations after the finest warp",
                                 lo=0, hi=50)
    iterations: int = _f(50, "maximum primal-dual iterations per warp", lo=1, hi=100000)
    tolerance: float = _f(0.0, "stop a warp early when the RMS flow update per iteration (px) falls "
                          "below this; 0 runs all iterations", lo=0.0, hi=1.0)
    pd_relaxation: float = _f(1.0, "over-relaxation rho of the primal-dual iteration on images: each step's "
                              "new primal and dual variables are moved rho times their change (1 = the plain "
                              "iteration; docs/engine.md 'Primal-dual')", lo=0.0, hi=1.99, lo_open=True)
    levels: int = _f(5, "maximum pyramid levels (1 = no coarse-to-fine)", lo=1, hi=30)
    scale_factor: float = _f(0.5, "pyramid downscale factor between levels", lo=0.2, hi=0.95)
    min_size: int = _f(16, "smallest image side allowed on the coarsest level (px)", lo=4, hi=100000)
    warps: int = _f(5, "warps (re-linearisations) per pyramid level", lo=1, hi=100)
    finest_warps: int = _f(0, "warps on the finest solved level (0 = warps): the level's flow starts from the "
                           "next coarser level's, and each warp there costs the most", lo=0, hi=100)
    finest_iterations: int = _f(0, "primal-dual iterations per warp on the finest solved level (0 = iterations)",
                                lo=0, hi=100000)
    finest_level: int = _f(0, "finest pyramid level solved (0 = full resolution); the flow of that level is "
                           "upsampled to full resolution (like DIS's finest_scale)", lo=0, hi=29)
    median_filter: int = _f(5, "median filter size applied to the flow after each warp (0 = off)",
                            choices=(0, 3, 5))
    median_weight_sigma: float = _f(0.0, "weighted median (Sun, Roth, Black 2010, 'Classic+NL'; docs/engine.md "
                                    "'Weighted median'): sigma of the frame-0 grey-value similarity (images in [0, 1]) "
                                    "that weighs a window's neighbours in the median after each warp; 0 = the plain "
                                    "median", lo=0.0, hi=10.0)
    median_occlusion_sigma: float = _f(0.15, "weighted median: sigma (1/frame) of the occlusion state "
                                       "1 / (1 + min(div v, 0)^2 / sigma^2) that weighs each neighbour (0 = none)",
                                       lo=0.0, hi=100.0)
    median_weight_warps: str = _f("every", "weighted median: after 'every' warp, after each level's 'last' warp only "
                                  "(the one whose flow the level hands on), after the finest solved level's last "
                                  "warp only ('finest'), or after every warp of the coarser levels and the finest "
                                  "solved level's last ('coarse'); the plain median after the others",
                                  choices=("every", "last", "finest", "coarse"))
    median_weight_range: float = _f(0.5, "weighted median: px; where both flow components' ranges over the "
                                    "3 x 3 window around a pixel are at most this the plain median stands (the "
                                    "weights only matter where a pixel is next to two motions; the cost goes there)",
                                    lo=0.0, hi=1000.0)
    level_alpha_factor: float = _f(1.0, "alpha on level l is alpha * level_alpha_factor**l "
                                   "(l = 0 finest; > 1 regularises coarse levels more)", lo=0.1, hi=10.0)
    tv_edge_weight: float = _f(0.0, "images only: a of the edge weight g = max(tv_edge_floor, "
                               "exp(-a (|grad I0_s| / s)^b)) of the first TV term, g |grad v| (Wedel et al. / "
                               "Werlberger et al. 2009): I0_s the level's frame 0 smoothed (Gaussian sigma 1), s the "
                               "mean of |grad I0_s| on that level (so g does not change with the image's contrast); "
                               "0 = off (plain TV)", lo=0.0, hi=100.0)
    tv_edge_power: float = _f(3.0, "b of the edge weight (tv_edge_weight): with 3 g falls at gradients 2-3 times "
                              "the level's mean", lo=0.1, hi=4.0)
    tv_edge_floor: float = _f(0.6, "least edge weight g (tv_edge_weight): the regulariser never drops below this "
                              "share of alpha (0.6: the value chosen for realtime; 0.1 failed the suite's report "
                              "split and let fastest's wiper keep its own motion, docs/engine.md)", lo=0.01, hi=1.0)
    tv_edge_min_level: int = _f(1, "the edge weight (tv_edge_weight) on pyramid levels >= this only (0 = every "
                                "level; the default 1 keeps plain TV at full resolution, where it cost the fine "
                                "synthetic textures and helped no regime)", lo=0, hi=29)
    incompressibility: float = _f(0.0, "volumes only (3-D flow): weight beta of the penalty (beta/2)|div v|^2 "
                                  "that makes the flow divergence-free (0 = off; the 2-D engine does not use it)",
                                  lo=0.0, hi=1000.0)
    warp_kernel: str = _f("bspline", "cubic kernel of the warp: bspline (prefiltered cubic B-spline) or keys "
                          "(Keys a = -1/2, Catmull-Rom); both reproduce linear ramps", choices=WARP_KERNELS)
    initialisation: str = _f("none", "flow the refinement starts from, fused per pixel with the pyramid's own: "
                             "none, OpenCV DIS (dis_ultrafast/dis_fast/dis_medium; dis_fine = medium down to full "
                             "resolution) or sparse descriptor "
                             "matches densified edge-aware (orb/sift)", choices=INITIALISATIONS)
    init_scale: float = _f(0.25, "with an initialisation, refinement restarts on the coarsest pyramid level "
                           "with at least this fraction of the input resolution", lo=0.0, hi=1.0, lo_open=True)
    init_finest_level: int = _f(0, "finest pyramid level solved for a pair the initialisation finds moving beyond "
                                "init_min_motion (the larger of this and finest_level; a caller's initial_flow "
                                "alone does not count): there the large-motion errors, not the full-size levels' "
                                "precision, limit the flow", lo=0, hi=29)
    init_min_motion: float = _f(24.0, "an initialisation the engine computes is fused only when its 95th-percentile "
                                "|flow| (px) exceeds this (smaller motions: the pyramid alone is more accurate; "
                                "0 = always)", lo=0.0, hi=10000.0)
    temporal_init: int = _f(0, "in a stream (node, flow_bag eval): 1 = the previous pair's flow, carried "
                            "forward, is an initialisation of the next pair", choices=(0, 1))
    reconstruction: str = _f("none", "none: the flow from the measured frames; joint: the paper's joint model of "
                             "motion and images (the images eliminated in closed form: the L1 data term becomes "
                             "J_gamma, quadratic for residuals below 2 image_gamma; docs/engine.md, 'Joint model'); "
                             "needs a model with an L1 data term", choices=RECONSTRUCTIONS)
    image_gamma: float = _f(0.01, "joint: weight gamma of the coupling C(u, v) = |u1(x + v) - u0(x)|_1 against the "
                            "images' fidelity (grey levels of the normalised frames: frames differing by less than "
                            "2 gamma along the flow are averaged)", lo=0.0, hi=10.0, lo_open=True)
    stream_levels: int = _f(0, "in a stream (node, flow_bag eval): the previous pair's flow, carried to the new "
                            "frame, starts the refinement on this many finest solved levels, skipping the coarser "
                            "ones and the initialisation while the prediction holds (0 = off: every pair solved "
                            "in full)", lo=0, hi=4)
    stream_warps: int = _f(2, "stream mode: warps per level refined from the prediction", lo=1, hi=100)
    stream_iterations: int = _f(10, "stream mode: primal-dual iterations per warp on those levels", lo=1,
                                hi=100000)
    stream_finest_warps: int = _f(0, "stream mode: warps on the finest solved level (0 = stream_warps): the "
                                  "level that costs the most per warp", lo=0, hi=100)
    stream_finest_iterations: int = _f(0, "stream mode: primal-dual iterations per warp on the finest solved level "
                                       "(0 = stream_iterations)", lo=0, hi=100000)
    stream_inner_median: int = _f(-1, "stream mode: median filter size after the warps of a level refined from "
                                  "the prediction but its last, which keeps median_filter (-1 = median_filter; "
                                  "0 = none)", choices=(-1, 0, 3, 5))
    stream_alpha: float = _f(0.0, "stream mode: regularisation weight of the refinement from the prediction (0 = "
                             "alpha; a pair solved in full always uses alpha)", lo=0.0, hi=1000.0)
    stream_relaxation: float = _f(0.0, "stream mode: pd_relaxation of the refinement from the prediction (0 = "
                                  "pd_relaxation)", lo=0.0, hi=1.99)
    stream_duals: float = _f(1.0, "stream mode: the carried regulariser duals are multiplied by this before the "
                             "refinement from the prediction (1 = as the previous pair left them; 0 = restarted "
                             "from zero, the flow alone carried)", lo=0.0, hi=1.0)
    stream_max_predicted: float = _f(0.2, "stream mode: the pair is solved in full when more than this fraction "
                                     "of the prediction's pixels is unexplained (its robust data cost on its "
                                     "start level: a scene cut, a jump of a few pixels such as camera shake)",
                                     lo=0.0, hi=1.0)
    stream_max_unexplained: float = _f(0.3, "stream mode: a previous flow, or a refined prediction, with more "
                                       "unexplained pixels than this is not used (full solve)", lo=0.0, hi=1.0)
    stream_margin: float = _f(0.05, "stream mode: a refined prediction explaining the pair worse than the "
                              "previous pair's flow by more than this fraction is replaced by a full solve",
                              lo=0.0, hi=1.0)
    stream_check_samples: int = _f(RELIABILITY_SAMPLES, "stream mode: about this many pixels are sampled by the "
                                   "unexplained fraction of a refined prediction (its check; a full solve's: "
                                   f"{RELIABILITY_SAMPLES})", lo=100, hi=1 << 40)
    stream_max_gap: float = _f(2.5, "stream mode: a pair whose stamp interval differs from the previous pair's "
                               "by more than this factor (a dropped run of frames) is solved in full; within "
                               "it the prediction is scaled by the ratio", lo=1.0, hi=1000.0)
    backend: str = _f("auto", "solver backend: numba kernels, numpy reference, or auto (numba if importable)",
                      choices=BACKENDS)
    threads: int = _f(0, "threads for the numba backend (0 = all cores)", lo=0, hi=1024)
    parallel_min_pixels: int = _f(0, "numba backend: pyramid levels of at least this many pixels run the "
                                  "solver's and the linearisation's parallel kernels (same results; 0 = the "
                                  "defaults, 120000 and 20000: thread start-up outweighs the gain below)",
                                  lo=0, hi=1 << 40)

    def __post_init__(self) -> None:
        if self.model in MODEL_WEIGHTS:  # an unknown model is reported by the field check below
            for name, value in MODEL_WEIGHTS[self.model].items():
                if getattr(self, name) is CALIBRATED:
                    object.__setattr__(self, name, value)
        for f in dataclasses.fields(self):
            object.__setattr__(self, f.name, _check_field(f, getattr(self, f.name)))
        if self.model in ("l1_tv_l2", "l1_tv_tv") and self.alpha1 <= 0.0:
            raise ConfigError(f"alpha1 must be > 0 for model {self.model!r} (got {self.alpha1})")
        if self.reconstruction == "joint" and MODEL_SPECS[self.model].data != "l1":
            raise ConfigError(f"reconstruction 'joint' needs a model with an L1 data term (its coupling C is L1), "
                              f"got {self.model!r}")
        if self.constraint == "mass" and self.photometric not in MASS_PHOTOMETRIC:
            raise ConfigError(f"constraint 'mass' needs photometric {' or '.join(MASS_PHOTOMETRIC)} (got "
                              f"{self.photometric!r}: it shifts or reshapes intensities, which changes mass)")
        if self.finest_level >= self.levels:
            raise ConfigError(f"finest_level must be < levels (got finest_level={self.finest_level}, "
                              f"levels={self.levels})")

    # ----------------------------------------------------------------------------------------- builders
    @classmethod
    def preset(cls, name: str) -> FlowConfig:
        """The named preset (``quality``, ``balanced``, ``realtime``, ``fastest``, ``joint``)."""
        if name not in PRESETS:
            raise ConfigError(f"unknown preset {name!r}; choose one of {', '.join(PRESETS)}")
        return cls(**PRESETS[name])

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any], base: FlowConfig | None = None) -> FlowConfig:
        """Build from a mapping of field names; a ``preset`` key selects the base first.

        Keys that are not config fields are an error (a typo must not be silently ignored).
        """
        values = dict(values)
        if "preset" in values:
            preset = values.pop("preset")
            if preset not in (None, ""):
                base = cls.preset(str(preset))
        base = base if base is not None else cls()
        unknown = sorted(set(values) - set(field_names()))
        if unknown:
            raise ConfigError(f"unknown parameter(s) {', '.join(unknown)}; "
                              f"valid: {', '.join(field_names())}")
        return base.replace(**values)

    @classmethod
    def from_yaml(cls, path: str | Path, base: FlowConfig | None = None) -> FlowConfig:
        """Load a YAML file: a plain mapping, or a ROS params file (``node: {ros__parameters: {...}}``).

        In a ROS params file, keys the engine does not know (node-only parameters such as QoS overrides)
        are ignored; in a plain mapping they are an error.
        """
        data = read_mapping(path)
        ros = ros_parameters(data)
        if ros is not None:
            keep = {k: v for k, v in ros.items() if k in field_names() or k == "preset"}
            return cls.from_mapping(keep, base)
        return cls.from_mapping(data, base)

    def replace(self, **changes: Any) -> FlowConfig:
        """A validated copy with ``changes`` applied; a change of ``model`` without ``alpha``/``alpha1``
        also sets them to the new model's calibrated weights and ``census_alpha`` to 0 (:func:`implied_weights`)."""
        unknown = sorted(set(changes) - set(field_names()))
        if unknown:
            raise ConfigError(f"unknown parameter(s) {', '.join(unknown)}")
        return dataclasses.replace(self, **implied_weights(self.model, changes),
                                   **implied_by_constraint(self.constraint, changes), **changes)

    def with_overrides(self, assignments: Iterable[str]) -> FlowConfig:
        """Apply ``key=value`` strings (CLI ``--set``), parsed by each field's type."""
        changes: dict[str, Any] = {}
        for item in assignments:
            key, sep, text = item.partition("=")
            key = key.strip()
            if not sep or not key:
                raise ConfigError(f"expected key=value, got {item!r}")
            if key not in field_names():
                raise ConfigError(f"unknown parameter {key!r}; valid: {', '.join(field_names())}")
            changes[key] = parse_value(key, text.strip())
        return self.replace(**changes)

    def to_dict(self) -> dict[str, Any]:
        """Plain dict of every field, in declaration order."""
        return dataclasses.asdict(self)


# The calibrated weights of each model: the defaults of alpha/alpha1 when a model is chosen without them.
# On normalised pairs (photometric="normalise", the default) with the default pyramid, the best of a grid on the 8
# Middlebury pairs (the retired `bench.accuracy --model-search`, its grid in docs/engine.md; BENCHMARKS.md,
# "Model-aware weights"). The census data term wants larger ones, given with it (docs/engine.md, "Model-aware
# weights").
MODEL_WEIGHTS: dict[str, dict[str, float]] = {
    "l2_l2": dict(alpha=0.0003, alpha1=0.5),
    "l2_tv": dict(alpha=0.0002, alpha1=0.5),
    "l1_tv": dict(alpha=0.03, alpha1=0.5),
    "l1_tv_l2": dict(alpha=0.03, alpha1=0.5),
    "l1_tv_tv": dict(alpha=0.02, alpha1=0.5),
}
# The pyramid the mass constraint implies (docs/engine.md, "Mass preservation", "Convergence"): the dualised data term
# moves smooth, nearly divergence-free flow errors slowly, and a fine pyramid (0.9 per level, 2 warps each) removes
# them level by level. On fine_320's shift pairs it took the mass model from 0.055 to 0.012 px (brightness: 0.015).
MASS_SCHEDULE: Mapping[str, Any] = MappingProxyType(dict(scale_factor=0.9, levels=28, warps=2))


def implied_by_constraint(current_constraint: str, changes: Mapping[str, Any]) -> dict[str, Any]:
    """What a change of the constraint implies: switching ``constraint`` to ``mass`` selects the photometric
    mode ``density`` (the one mode that keeps mass: a pure gain) and the fine pyramid MASS_SCHEDULE, each
    unless ``changes`` gives it; else {}. One rule for every entry point, like :func:`implied_weights`."""
    if changes.get("constraint", current_constraint) != "mass" or current_constraint == "mass":
        return {}
    implied = {"photometric": "density", **MASS_SCHEDULE}
    return {k: v for k, v in implied.items() if k not in changes}


def implied_weights(current_model: str, changes: Mapping[str, Any]) -> dict[str, float]:
    """The weights a change implies: when ``changes`` switches the model away from ``current_model`` and does
    not give ``alpha`` / ``alpha1``, the new model's calibrated values of those (MODEL_WEIGHTS), and
    ``census_alpha`` 0 (the census term then weighs with the new model's alpha: a preset's census alpha is
    chosen for its own model, and an ``l2_*`` model's alpha is ~100x smaller); else {}.

    The one rule for every entry point (API ``replace``, CLI ``--model``, the node's ``model`` parameter):
    re-selecting the current model, or giving a weight with it, keeps what was given."""
    model = changes.get("model", current_model)
    if model == current_model or model not in MODEL_WEIGHTS:
        return {}
    return {k: v for k, v in {**MODEL_WEIGHTS[model], "census_alpha": 0.0}.items() if k not in changes}


def field_names() -> tuple[str, ...]:
    return tuple(f.name for f in dataclasses.fields(FlowConfig))


def fields_info() -> list[FieldInfo]:
    """Name, type, default, description and range of every field (alpha/alpha1: the default model's
    calibrated weights)."""
    return settings_fields_info(FlowConfig)


def parse_value(key: str, text: str) -> Any:
    """Parse ``text`` for field ``key`` by the field's declared type."""
    info = {i.name: i for i in fields_info()}[key]
    try:
        if info.type is int:
            return int(text)
        if info.type is float:
            return float(text)
    except ValueError:
        raise ConfigError(f"{key}: expected {info.type.__name__}, got {text!r}") from None
    return text
