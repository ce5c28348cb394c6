"""Per tune regime: how many pairs the rule blurs beyond the stage's own presmoothing, and the blur range, per preset and c."""
import sys
import numpy as np
from bench.suite.regimes import REGIMES
from bench.suite.methods import unit_grey
from flow_node.core.backends import NUMPY
from flow_node.core.config import FlowConfig
from flow_node.core.engine import photometric_stage
preset, cs = sys.argv[1], [float(c) for c in sys.argv[2].split(",")]
regs = sys.argv[3].split(",")
print(f"| {preset}: regime (pairs) | " + " | ".join(f"c = {c:g}" for c in cs) + " |")
print("|---|" + "---|" * len(cs))
for name in regs:
    samples = [s for s in REGIMES[name].build(sys.argv[4] if len(sys.argv) > 4 else "tune", False) if len(sys.argv) < 6 or s.variant.startswith(sys.argv[5])]
    cells = []
    for c in cs:
        cfg = FlowConfig.preset(preset).replace(census_noise_smooth=c)
        bl = []
        for s in samples:
            i0, i1 = unit_grey(s.f0, s.bits), unit_grey(s.f1, s.bits)
            _, j = photometric_stage(i0, i1, cfg, NUMPY)
            if j.noise is not None and j.noise.base_blur is not None:
                bl.append(j.noise.blur)
        cells.append(f"{len(bl)}" + (f" ({min(bl):.1f}-{max(bl):.1f} px)" if bl else ""))
    print(f"| {name} ({len(samples)}) | " + " | ".join(cells) + " |")
