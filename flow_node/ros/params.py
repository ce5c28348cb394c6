"""The node's ROS parameters: one table built from the field metadata of FlowConfig (engine) and MotionSettings
(derived outputs, ``motion.*``) plus a few node-only entries.

Descriptors (description, ranges, read_only), the validation of a would-be parameter set, the expansion of
``preset`` into its group of values and the YAML files in config/ are all derived from :func:`param_specs`,
so defaults and ranges are never written twice. ``python -m flow_node.ros.params [PRESET]`` prints the
parameter file (``config/flow_node.yaml`` without a preset, ``config/<preset>.yaml`` with one).
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from ..core.config import PRESETS, FlowConfig, field_names, fields_info, implied_by_constraint, implied_weights
from ..core.errors import ConfigError
from ..core.settings import fields_info as settings_fields_info
from ..core.settings import from_flat
from ..pipeline.derived import MotionSettings
from ..pipeline.stream import COLOR_MAX_FLOW_RANGE, FLOW_UNITS, INPUT_SCALE_RANGE, StreamSettings


@dataclass(frozen=True)
class ParamSpec:
    """One ROS parameter: name, Python type (bool/int/float/str), default, description, range or choices."""

    name: str
    type: type
    default: Any
    description: str
    lo: float | None = None
    hi: float | None = None
    choices: tuple[Any, ...] | None = None
    read_only: bool = False


# Engine fields that cannot change while running: a backend/thread switch re-selects (and may JIT-compile)
# the solver mid-stream, and numba's thread pool size is fixed once started. No preset sets them.
READ_ONLY_FIELDS = frozenset({"backend", "threads"})

# The node's default preset: started without a params file it keeps up with a 30 Hz VGA camera on 2 cores.
# stream_fast solves a single pair, and every pair its checks reject, as fastest does, and the pairs of a
# steady stream from the previous pair's state (docs/node.md, "Defaults"; docs/engine.md, "The stream mode").
NODE_PRESET = "stream_fast"

# The derived outputs' settings (MotionSettings' fields, nested ones flattened) are parameters under this
# prefix: motion.samples, motion.mask.abs_px, motion.detector.on_frames, ...
MOTION_PREFIX = "motion."


def param_specs() -> list[ParamSpec]:
    """Every parameter of the node, engine fields first (in FlowConfig order), then the derived outputs'
    (MotionSettings, ``motion.*``), then node-only ones.

    The engine fields' defaults are those of NODE_PRESET (``preset`` defaults to it)."""
    defaults = StreamSettings()
    engine = FlowConfig.preset(NODE_PRESET)
    specs = [ParamSpec("preset", str, NODE_PRESET, "named group of engine settings applied when set: "
                       + ", ".join(PRESETS) + " ('' = none); it sets every engine setting but backend and "
                       "threads (a setting the preset does not list takes FlowConfig's default); explicit "
                       "values set together with it win", choices=("",) + tuple(PRESETS))]
    for f in fields_info():
        specs.append(ParamSpec(f.name, f.type, getattr(engine, f.name), f.help, f.lo, f.hi, f.choices,
                               f.name in READ_ONLY_FIELDS))
    specs += [ParamSpec(f.name, f.type, f.default, f.help, f.lo, f.hi, f.choices)
              for f in settings_fields_info(MotionSettings, MOTION_PREFIX)]
    specs += [
        ParamSpec("input_scale", float, defaults.input_scale,
                  "process frames shrunk by this factor; flow is published at that resolution, in pixels of the "
                  "shrunk image (multiply by 1/input_scale for full-resolution pixels)", *INPUT_SCALE_RANGE),
        ParamSpec("color_max_flow", float, defaults.color_max_flow,
                  "flow length (in flow_units) drawn at full saturation in ~/flow_color; 0 = each frame's "
                  "maximum", *COLOR_MAX_FLOW_RANGE),
        ParamSpec("flow_units", str, defaults.flow_units, "units of ~/flow and ~/magnitude: px/frame (displacement "
                  "over the pair) or px/s (divided by the pair's interval, ~/flow_pair)", choices=FLOW_UNITS),
        ParamSpec("use_compressed", bool, False, "subscribe to <image>/compressed (sensor_msgs/CompressedImage, "
                  "decoded with OpenCV) instead of image", read_only=True),
        ParamSpec("mask_file", str, "", "validity mask image (nonzero = valid, the input frames' size) for every "
                  "frame until a ~/mask message replaces it; '' = none (docs/node.md, 'Validity mask')",
                  read_only=True),
        ParamSpec("diagnostics_period", float, 1.0, "seconds between /diagnostics messages", 0.05, 60.0,
                  read_only=True),
        ParamSpec("hardware_id", str, "", "hardware_id in diagnostics ('' = frame_id of the input images)",
                  read_only=True),
        ParamSpec("warmup", bool, True, "run one small solve at start-up so the first frame is not a JIT "
                  "compile", read_only=True),
        ParamSpec("managed", bool, False, "lifecycle: false = the node configures and activates itself at "
                  "start-up; true = it starts unconfigured and waits for a lifecycle manager (ros2 lifecycle "
                  "set, the launch file's managed:=true)", read_only=True),
    ]
    return specs


def specs_by_name() -> dict[str, ParamSpec]:
    return {s.name: s for s in param_specs()}


def coerce(spec: ParamSpec, value: Any) -> Any:
    """``value`` as the parameter's type where that is lossless (int -> float for doubles)."""
    if spec.type is float and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    return value


def settings_from_values(values: Mapping[str, Any]) -> StreamSettings:
    """Validate a complete would-be parameter set; returns the stream settings or raises ConfigError.

    ``values`` maps parameter names to values (unknown names are ignored: QoS overrides, use_sim_time).
    ``preset`` is NOT applied here (it was expanded into its values when it was set).
    """
    preset = values.get("preset", "")
    if preset not in specs_by_name()["preset"].choices:
        raise ConfigError(f"preset: {preset!r} is not one of {', '.join(PRESETS)} (or '')")
    cfg = FlowConfig.from_mapping({k: values[k] for k in field_names() if k in values})
    defaults = StreamSettings()
    return StreamSettings(cfg, input_scale=values.get("input_scale", defaults.input_scale),
                          color_max_flow=values.get("color_max_flow", defaults.color_max_flow),
                          flow_units=values.get("flow_units", defaults.flow_units))  # validated there


def motion_from_values(values: Mapping[str, Any]) -> MotionSettings:
    """The derived outputs' settings from the ``motion.*`` parameters in ``values`` (others ignored, missing
    ones take MotionSettings' defaults); ConfigError naming the parameter if one is invalid."""
    return from_flat(MotionSettings, values, MOTION_PREFIX)


def preset_values(name: str) -> dict[str, Any]:
    """The parameter values a preset sets, typed per parameter; ConfigError if unknown.

    Its whole group: every engine field but the read-only ones, with FlowConfig's default where the preset
    does not list a field, so that switching presets never keeps a value of the one before (realtime's
    ``finest_level: 1`` must not survive a switch to quality). Exactly ``FlowConfig.preset(name)``.
    """
    if name not in PRESETS:
        raise ConfigError(f"preset: {name!r} is not one of {', '.join(PRESETS)} (or '')")
    specs = specs_by_name()
    return {k: coerce(specs[k], v) for k, v in FlowConfig.preset(name).to_dict().items()
            if k not in READ_ONLY_FIELDS}


def declared_defaults(preset: str) -> dict[str, Any]:
    """The default of every parameter but ``preset`` when the node starts with ``preset``: its values over
    the specs' defaults, so a params file with ``preset: realtime`` and ``iterations: 20`` means realtime
    with 20 iterations. An unknown preset adds nothing here (configure then fails with the reason)."""
    try:
        base = preset_values(preset) if preset else {}
    except ConfigError:
        base = {}
    return {s.name: base.get(s.name, s.default) for s in param_specs() if s.name != "preset"}


def expand_preset(given: list[tuple[str, Any]], model: str, constraint: str) -> list[tuple[str, Any]]:
    """What a set of parameters ``given`` (name, value) implies besides itself: a ``preset`` its group, a new
    model without weights its calibrated ones (config.implied_weights; ``model`` is the current one), the
    mass constraint its density mode and fine pyramid (config.implied_by_constraint; ``constraint`` the current
    one); values given in the same call win. An unknown preset implies nothing (validation rejects it with
    the reason)."""
    specs, names = specs_by_name(), {name for name, _ in given}
    out = list(given)
    for name, value in given:
        if name == "preset" and value and isinstance(value, str):
            try:
                group = preset_values(value)
            except ConfigError:
                continue
            out += [(k, coerce(specs[k], v)) for k, v in group.items() if k not in names]
    implied = dict(out)
    return (out[len(given):] + list(implied_weights(model, implied).items())
            + list(implied_by_constraint(constraint, implied).items()))


def _yaml_value(value: Any) -> str:
    """A YAML scalar that keeps the ROS type: doubles always with a decimal point or exponent."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        text = repr(value)
        return text if any(c in text for c in ".en") else text + ".0"
    if isinstance(value, str):
        return f'"{value}"'
    return str(value)


def render_yaml(preset: str | None = None) -> str:
    """The ROS parameter file: every parameter with its default, or ``preset`` and the values it sets."""
    lines = ["# Generated by `python -m flow_node.ros.params"
             + (f" {preset}`" if preset else "`") + "; test_node_params checks it stays in sync.",
             "# Parameters of the flow_node node (any node name: /**). See docs/node.md.",
             "/**:", "  ros__parameters:"]
    if preset:
        preset_values(preset)  # ConfigError for an unknown name
        lines.insert(2, "# The preset's values live in one place, flow_node/core/config.py (PRESETS); the node expands")
        lines.insert(3, "# `preset` into them at start-up. Parameters added below it override single values.")
        lines.append(f"    preset: {_yaml_value(preset)}")
    else:
        for s in param_specs():
            lines.append(f"    # {s.description}" + (" (read-only)" if s.read_only else ""))
            lines.append(f"    {s.name}: {_yaml_value(s.default)}")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    sys.stdout.write(render_yaml(args[0] if args else None))
    return 0


if __name__ == "__main__":
    sys.exit(main())
