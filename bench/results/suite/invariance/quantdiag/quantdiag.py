"""One-off (session 26): is the fine textures' tone-curve cost the 8-bit quantisation after the curve, or the
data term? Report split's synthetic pairs, each report family's grey variants, frame 2 changed and then (a) quantised
to 8 bit as the suite does, (b) kept in float; the unchanged pair both ways. Mean AEE per preset."""
import sys, json
import numpy as np
from flow_node.core import FlowConfig, FlowEstimator
from flow_node.bag.scenes import render_grey_pair
from bench.suite import synthetic
from bench.suite.photometric import SIZE, SPAN, variants
from bench.suite.synthetic import quantise

def aee(f, gt):
    return float(np.linalg.norm(f - gt, axis=-1).mean())

presets = sys.argv[1].split(",")
def cfg(p):
    name, _, rest = p.partition(":")
    kw = {k: float(v) for k, v in (x.split("=") for x in rest.split(";") if x)}
    return FlowConfig.preset(name).replace(**kw)
ests = {p: FlowEstimator(cfg(p)) for p in presets}
rows = {}
for k, s in synthetic.seeds("report", 4):
    scene, label = synthetic.scene_for(k, s, SIZE, span=SPAN)
    i0, i1, gt = render_grey_pair(scene)
    gt = gt.astype(np.float32)
    cases = [("unchanged", i1)] + [(v.label, v(i1, s)) for v in variants("report", rgb=False)]
    for name, f1 in cases:
        for mode in ("8bit", "float"):
            if mode == "8bit":
                a, b = quantise(i0, 8).astype(np.float32) / 255, quantise(f1, 8).astype(np.float32) / 255
            else:
                a, b = i0.astype(np.float32), f1.astype(np.float32)
            for p, e in ests.items():
                rows.setdefault((p, name.split("/")[0], mode), []).append(aee(e.estimate_grey(a, b).flow, gt))
out = {}
for p in presets:
    print(p)
    fams = sorted({f for (q, f, m) in rows if q == p}, key=lambda f: (f != "unchanged", f))
    for f in fams:
        q8, fl = np.mean(rows[(p, f, "8bit")]), np.mean(rows[(p, f, "float")])
        u8, uf = np.mean(rows[(p, "unchanged", "8bit")]), np.mean(rows[(p, "unchanged", "float")])
        print(f"  {f:14s} 8-bit {q8:.4f} ({q8 / u8:.2f}x)   float {fl:.4f} ({fl / uf:.2f}x of float unchanged, {fl / u8:.2f}x of 8-bit unchanged)")
        out[f"{p}/{f}"] = {"8bit": q8, "float": fl}
json.dump(out, open(sys.argv[2], "w"), indent=1)
