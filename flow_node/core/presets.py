"""The named presets (FlowConfig.preset): each one's whole set of fields in one literal, and why.

Pure data: config.py turns a preset into a FlowConfig (and re-exports these names); the values are chosen
on the suite (docs/engine.md, "Presets").
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

# The named presets, each complete in one place. Re-tuned on the suite as a whole (issue 11: bench.suite tune
# split plus the 8 Middlebury pairs), after the exact warp and the photometric stage. Why each value:
# docs/engine.md, "Presets"; the measurements behind them: `git show a451d03:BENCHMARKS.md` (issue 11 sections)
# and bench/results/suite/tune/.
# - quality: many short warps per level on a fine pyramid (Middlebury <= 0.30); balanced: 2 x 15, alpha 0.035
#   (ahead of DIS medium on sensor noise); realtime: 4 x 6 on the coarse levels, 2 x 16 at full size (the
#   level that costs); fastest: half size, 4 warps per level, 10 iterations per coarse warp.
# - initialisation (issue 12, docs/engine.md "Large displacements"): every preset starts from OpenCV DIS where a
#   pair moves more than init_min_motion; the DIS preset is the one of similar cost, quality's is DIS medium
#   down to full resolution (dis_fine: ~3x DIS medium's time, on ../shared/data/large 60.7 summed AEE over
#   the 7 pairs against 61.7 with dis_medium, both with the occlusion-aware fusion; on the large-motion bags
#   the two are level, 23.02 vs 22.97 on merged main, at ~1.4x the time). Middlebury and the suite's
#   small-motion regimes (under 24 px) are unchanged by construction.
# - init_finest_level: the speed presets refine a pair the initialisation is fused on down to quarter size only
#   (the level it enters at): on the large set and the large-motion bags the finer levels changed the AEE by
#   < 2 % and cost ~3/4 of realtime's time (docs/engine.md, "Presets"; BENCHMARKS.md, "Large motions at a
#   bounded cost").
# - census schedule (issue 25, docs/engine.md "Presets", third round): with photometric=census, quality and realtime
#   anti-alias only the three finest pyramid steps and use EPS 0.03 on levels under 50 px wide (chosen on the
#   suite's tune split); balanced anti-aliases the four finest steps (below), fastest solves at half size (every
#   step anti-aliased anyway) and uses the coarse EPS on empty levels (census_empty_contrast; issue 25, task blob:
#   on zoomed finest-band textures the texture-free 40 px coarsest level locked its flow into a wrong minimum,
#   tune seed 62 0.68 px; a width rule cost real_exact 2 %; since task
#   flatcensus fastest has both rules, below). The two
#   rules stay two (issue 25, task dampunify, tune split): for quality and realtime the contrast rule alone is
#   worse at every threshold tried (0.001-0.02; geomean 1.003-1.22): the median contrast of a faint texture at
#   full resolution is ~0.004 (thresholds >= 0.005: low_contrast 1.3-4.6x), and below that damping the faint but
#   textured < 50 px levels the width rule damps helps them (low_contrast +5 %, real_exact +1.7 % without it).
#   realtime adds the contrast rule at 0.002 beside its width rule (issue 25, task zoom640, tune split): at 640x480
#   its 80 px level holds no texture of the finest band (contrast ~4e-5) but is over 50 px wide; undamped it locked
#   zoomed/shifted finest-band pairs into wrong minima (tune seed 62: 0.195 -> 0.012 px; 68 tune seeds 0.0143 ->
#   0.0081 mean; other tune regimes within 0.6 %). A width fraction instead (damp under 16 % of the input width)
#   cost Middlebury 3.3 %. quality keeps the width rule alone (its 640x480 failure is another one: engine.md).
#   That one is aliasing (issue 25, task q640, tune split): anti-aliasing every step fixes tune seed 62 (0.98 ->
#   0.007 px) but costs real_exact 15 % (from the fifth step on), so quality keeps 3 steps (engine.md, ninth round).
#   fastest adds realtime's width rule beside its contrast rule (issue 25, task flatcensus, tune split): damping
#   the 40 px coarsest level even where it still holds a faint texture took the flat regime 0.0672 -> 0.0632
#   (grey values 0.0634), tune geomean 0.988 over nine regimes (real_exact +2.1 %, the worst); the width rule
#   alone (contrast rule off) failed a 640x480 tune pair whose 80 px level is empty (0.115 -> 0.435 px). Report
#   split once: every regime within 1 % (flat +1.0 %: the tune gain did not carry over), large set 10.70 -> 10.65.
#   realtime's census term is L1 in earnest (issue 25, task smoothbags, tune data only): with DELTA 0.2 nearly every
#   signature residual lay in the majoriser's quadratic zone, a quadratic term pulls less than TV near the solution
#   and the flow's gradient shrank (rendered 128x96 rotation/zoom/deformation tune scenes 0.044 against grey 0.029).
#   DELTA 0.07 with alpha 0.08 (the stronger pull balanced): tune scenes 0.044 -> 0.037, suite tune split geomean
#   0.969 (fine_640 +1.4 %, the worst regime; Middlebury -5 %).
#   quality's too (issue 25, task qdelta, tune split): census_alpha 0.045 (what users set by hand before: the same
#   flows), then DELTA 0.03 with census alpha 0.16: tune geomean 0.920 over eight regimes against DELTA 0.2 / 0.045
#   (low_contrast -19 %, Middlebury -4 %, fine_640 -0.4 %: none worse); DELTA 0.07 / 0.1 0.951, 0.03 / 0.13 0.929
#   but fine_640 +3 %; a lower alpha costs real_exact (0.03 / 0.10: +9 %).
#   quality's finest solved level compares the ring at distance 2 (census_finest_radius 2; issue 25, eleventh round,
#   tune split): with the L1 term in earnest the ring no longer trades invariance for little (censwin): radius 2
#   with DELTA 0.05 / alpha 0.10 took the tune geomean to 0.887 of the DELTA 0.2 / 0.045 setting (Middlebury 0.290,
#   real_exact -13 %, none worse; qdelta's 0.03 / 0.16 alone 0.920); radius 2 with 0.03 / 0.16 read 0.865 but
#   Middlebury 0.298, over quality's 0.295 bound, so 0.05 / 0.10.
#   fastest's too (issue 25, task fastdelta, tune data only): on the same rendered tune scenes fastest census lost
#   more (0.124 against grey 0.091, deformation 0.126 against 0.056). DELTA 0.01-0.03 with alpha 0.1-0.14 beat
#   grey there but broke the suite's tune split (low_contrast +37-64 %, fine-texture pairs into wrong minima at
#   lower alpha); the smaller DELTA must come with a much larger alpha. DELTA 0.05 with alpha 0.2: tune scenes
#   0.124 -> 0.108, suite tune split geomean 0.928 over 8 regimes (low_contrast +2.1 %, the worst; Middlebury
#   -5 %, real_exact -7 %, fine 320 -17 %). Report split once: every regime better (bags 0.133 -> 0.118, grey 0.107;
#   flat 0.063 -> 0.055, grey 0.055; large 10.65 -> 10.58), geomean 0.904.
#   Then further along the same curve (issue 25, task fastbags, tune data only): DELTA 0.02 with alpha 0.35. On the
#   128x96 tune scenes the finer level inherits the 32 px level's census flow (with that level's data term damped
#   the final flow is better); medians, the ring and iteration splits move the scenes -2..+5 %, a larger
#   census_coarse_eps helps them 3-5 % but costs the tune split's flat regime 18-26 %. A smaller DELTA helps if
#   alpha grows with it (0.05/0.2 -> 0.03/0.26 -> 0.02/0.35: low_contrast stays within +2.5 %). Tune scenes 0.108
#   -> 0.097 (grey 0.091), suite tune split geomean 0.960 over 8 regimes (low_contrast +2.3 %, the worst; real_exact
#   +1.2 %, fine 320 -14 %; DELTA 0.017 / alpha 0.38 read 0.958 but low_contrast +2.9 %). Report split once: every
#   regime better (bags 0.118 -> 0.108, grey 0.107; Middlebury 0.466 -> 0.461; real_exact 0.394 -> 0.388, grey
#   0.387; large 10.58 -> 10.38), geomean 0.944.
#   Then a smaller signature EPS with it (issue 25, task feps, 2026-12-07; bench/results/suite/invariance/feps):
#   census_eps 0.007 (was CensusParams' 0.01) with census_alpha 0.36. Tune split, 13 regimes, 35 settings over EPS
#   0.005-0.0075, alpha 0.30-0.45, DELTA 0.015-0.05, census_coarse_eps, census_noise_k: EPS 0.005 at alpha 0.35 gained
#   the real images 6-9 % but lost missing (+3 %, the wiper stripes pair) and low_contrast (+6 %); a larger alpha wins
#   low_contrast back and a smaller DELTA missing, but not both. 0.007 / 0.36 is the best that passes: Middlebury -4.6
#   %, real_exact -2.8 %, real_exact_photometric -3.3 %, photometric_real -3.3 %, the worst low_contrast +0.00095 px
#   (+2.5 %) and missing +0.0009 px, within max(0.001 px, 0.5 %) only by the 0.001 px. Report split once: real_exact
#   0.3238 -> 0.3110 (OpenCV DualTVL1 0.313), Middlebury 0.4374 -> 0.4174, real_exact_photometric 0.3564 -> 0.3439, the
#   worst fine_640 +0.0004 px (+2.4 %), geomean 0.992; S-curve on real photos 1.19x -> 1.16x, low light 1.28x -> 1.33x
#   (its AEE equal, the unchanged pairs gained). No work changes (EPS and alpha only). stream_fast keeps 0.01 / 0.35:
#   the stream regime (tune, 320x240) lost 1.5 % with them (0.03841 -> 0.03899; every EPS 0.007-0.0075 candidate 0.9-1.5
#   %, stream_alpha does not help).
# - quality compares census signatures by default (photometric=census; issue 25: invariant by construction, no
#   detection): with the eleventh round's setting its report split beat its grey-value data term on every regime
#   but real_exact (+1.7 %, 0.239 against 0.235; Middlebury 0.290 against 0.295, bags 0.057 / 0.066, large 8.12 /
#   8.46, noise 0.024 / 0.055, the tone and illumination families 0.315 / 5.26 px) at 1.1x its CPU time
#   (git show 4983857:bench/results/suite/invariance/qr2/flip.md). photometric=normalise gives the grey-value term back.
# - census time (issue 25's time round 5, docs/engine.md "The census data term", What it costs): with
#   photometric=census, quality runs 8 primal-dual iterations per warp (12 with grey values) and fastest a 3 x 3
#   median after each warp but a level's last; chosen on the suite's tune split (Middlebury, photometric_real,
#   real_exact), checked once on the report split. realtime's cuts that reached 1.15x then lost accuracy
#   (git show 4983857:bench/results/census_cost/census5/summary.md); its census schedule since is task
#   cschedule's (below).
#   Grey-value flows are unchanged (census fields only).
#   Task cschedule re-tried it with the radius-2 ring, a re-tuned census alpha and one finest warp
#   (census_finest_warps 1 x 28: 1.14x, tune geomean 0.99-1.00) and fastest's cuts (>= 1.22x): every cut at or under
#   1.21x lost low_contrast 8.7 % or more on the tune split against today's census
#   (git show 4983857:bench/results/suite/invariance/cschedule/summary.md), fastest keeps its schedule.
# - realtime compares census signatures by default (issue 25, sixteenth round; invariant by construction, no
#   detection). Its census schedule is cschedule's 1.14x point of the best tune geomean whose Middlebury stays
#   within 3 % (radius-2 ring on the finest level, one warp of 28 there, census alpha 0.10): report split bags
#   +2.9 %, large +3.0 %, Middlebury 0.395 (<= 0.404), every other regime better. Reverted once (fourteenth round)
#   for its time, +13-40 % outside Middlebury; since task censlarge's kernels (flows bit-identical) it is 1.04-1.09x
#   its grey-value time on Middlebury, fine 320x240 and the bags, and 1.26-1.29x on the large set, where one pair
#   (toy_square) misses its initialisation (bench/results/census_cost/censlarge/summary.md; docs/engine.md
#   "Presets"). photometric=normalise gives the grey-value term back.
# - fastest compares census signatures by default (issue 25, seventeenth round, 2026-12-06), and so stream_fast, the
#   node's default: task fastcens's kernels (flows bit-identical) brought its census time to 1.10-1.16x its grey
#   time (bench/results/census_cost/fastcens/summary.md), task fastbags' DELTA / alpha (above) its bags within 1 %
#   of grey values, and the initialisation's tail rule (initialise.TAIL_FACTOR) its large set below grey values;
#   Middlebury 0.461 against 0.564. stream_lite kept grey values until task litezd (2026-12-07): with carried duals
#   census lost at quarter size on the stream regime's tune split (0.048 -> 0.058-0.073 over six census settings);
#   with the duals restarted and DELTA 0.003 it ties grey values at 0.66x the CPU (its line below).
#   photometric=normalise gives the grey-value term back.
# - balanced compares census signatures by default (issue 25, task balcens3, 2026-12-07), with the edge-weighted TV
#   at a 0.08 (below): quality's census delta / alpha and finest ring, the coarse EPS rule, four anti-aliased steps,
#   12 census iterations per warp and one finest warp of 30. Tune split (22 settings): with the weight, 3 steps
#   aliased a 640x480 band-3 rotation (fine_640 +12 %) and 5 steps or all of them failed missing's unmasked wiper
#   pair (+55 %, +97 %); 4 steps with a 0.065-0.10 kept both, and 12 iterations (of 15) the bags under 1.15x CPU
#   time (0.95-1.09x grey balanced; with 15 1.12-1.17x on the bags). Report split once against grey balanced:
#   real_exact +3.3 % (0.2533 -> 0.2616; without the weight, task balcens2, +9.1 %), every other regime better
#   (Middlebury 0.338 -> 0.329, bit_depth -9 %, missing -9 %, the tone families 1.6-4.1 px -> 0.02-0.35 px)
#   (bench/results/suite/invariance/balcens3/summary.md). photometric=normalise,tv_edge_weight=0 gives the former
#   preset back.
# - realtime presmooths every census pair by 0.45 px (census_presmooth; task presm, 2026-12-07): before, only
#   coarsely quantised pairs were blurred (QUANT_SIGMA), so 10-16-bit and high-contrast 8-bit frames were compared
#   unsmoothed and realtime read 10/12/16-bit fine textures 1.11-1.13x its 8-bit AEE (the suite's target: 1.10x).
#   Tune split, sigma in {0.3, 0.4, 0.45, 0.5, 0.6, 0.7, 1.0}: 0.45 is the largest that loses no tune regime
#   (real_exact -2.4 %, bit_depth -4.0 %, Middlebury -1.3 %, bags +0.2 %); 0.5 lost the unmasked wiper pairs (missing
#   +1.0 %: a blur spreads garbage), 0.6-1.0 the bags (+2.7-14 %). Report split once: 10/12/16 bit 1.10 / 1.08 / 1.08x
#   (was 1.13 / 1.12 / 1.11x), Middlebury 0.3854 -> 0.3805, real_exact 0.3019 -> 0.2960, missing +0.7 % (+0.0026 px,
#   the wiper pairs again), large +0.3 %. balanced (0.45: report large +0.6 %, missing +1.0 %, and no bit-depth miss
#   to mend), quality (0.4-0.45 tip its unmasked wiper pair from 2 to 30 px, 0.5 costs the bags 3 %) and fastest /
#   the stream presets (at half size the blur stacks on the anti-alias blur: tune Middlebury +1.0 %, bags +1.8 %)
#   keep 0 (docs/engine.md, "The census data term"; bench/results/suite/presm/summary.md).
CENSUS_SCHEDULE: Mapping[str, Any] = MappingProxyType(dict(census_antialias=3, census_coarse_eps=0.03,
                                                           census_coarse_width=50))
# The edge-weighted TV (issue 25, task edgetv; docs/engine.md "Edge-weighted TV"): realtime and fastest weigh their TV
# term by g = max(0.6, exp(-0.05 (|grad I0_s| / s)^3)) on every level but full resolution (tv_edge_min_level 1), so
# the foreground's motion spills less into the background beside a motion boundary that is an image edge. realtime,
# tune split: real_exact -8.5 %, Middlebury -2.6 %, every other tune regime within 0.0003 px; report split:
# real_exact 0.3156 -> 0.3019 (DualTVL1 0.3130), the worst regime photometric +0.0007 px; with census and the weight
# 0.99-1.11x grey values' CPU time (bench/results/suite/invariance/edgetv/). A floor of 0.1 gained more on tune
# (real_exact -20 %) but not on the report split (-9.5 %, synthetic photometric +17 %, fine_320 +18 %).
# fastest (and stream_fast, its fields) since task edgecost: the weight gained there too (tune real_exact -17.5 %,
# Middlebury -3.7 %), but g by OpenCV / numpy calls cost +4-7 % CPU time and took census + weight over issue 25's
# 15 % on the bags; g's kernel (numba_edges, 3.2x cheaper) made the weight +1-2 % (medians of six runs; the bags
# 1.068x -> 1.009x census alone), census + weight 1.04-1.16x grey values under load 2.4-4.3 (the bags 1.10-1.16x,
# census alone 1.09-1.15x there; at load 1-2.6 1.05-1.14x, the bags 1.12 / 1.14; quiet, at the merge, 1.07-1.10x, the
# bags 1.099 in both runs; bench/results/suite/invariance/edgecost/). Report split: real_exact 0.3883
# -> 0.3520, Middlebury 0.4614 -> 0.4445, worst fine_320 +0.0003 px. stream_lite kept plain TV until task litezd
# (stream tune 0.0481 -> 0.0486 with grey values); with census it takes fastest's weight. balanced weighs by a
# 0.08 (task balcens3, above: with its four anti-aliased census steps a 0.05 lost the missing regime's wiper pair on
# tune).
EDGE_TV: Mapping[str, Any] = MappingProxyType(dict(tv_edge_weight=0.05))  # tv_edge_floor 0.6: the field's default
# The weighted median (issue 25, task occl; docs/engine.md "Weighted median"): fastest (and stream_fast, its fields)
# replaces the plain median after each level's last warp by one whose neighbours count by frame 0's grey-value
# similarity and an occlusion state, where a pixel's 3 x 3 window spans more than 0.75 px. Tune split: real_exact
# -9.9 %, real_exact_photometric -7.9 %, Middlebury -0.8 %, no regime worse; CPU time 1.02-1.05x on Middlebury,
# 1.02x on the bags. Report split: real_exact 0.3520 -> 0.3315, worst missing +0.0004 px. After every warp it
# gained 2.5x as much (tune real_exact -24 %; report 0.3133) at 1.20-1.23x the time on Middlebury.
# balanced has it at range 1.5 px (task occl2; bench/results/suite/occl2): tune real_exact -12.3 %, Middlebury -1.6 %,
# no regime worse; CPU 1.06x Middlebury, 1.04x bags (0.75 px: 1.11x); report split every regime better (geomean
# 0.933). quality has fastest's setting (occl2): tune real_exact -13.5 %, no regime worse; CPU 1.02-1.04x
# Middlebury, 1.01x bags; report every regime better or equal (real_exact 0.2314 -> 0.2140, geomean 0.976).
# realtime keeps the plain median: a fixed cost (+2-5 % on Middlebury at any range) left its +4 % only at a range of
# 3 px, where the gain is small (tune real_exact -2 %).
# fastest weighs every warp of its coarser levels and the finest solved level's last (`coarse`, task wmfast, bench/
# results/suite/wmfast): tune real_exact -6.1 %, Middlebury -0.8 %, no regime worse; CPU 1.01-1.02x on Middlebury
# (six runs), 1.00-1.02x bags; report split every regime better or equal (real_exact 0.3315 -> 0.3238, DualTVL1 0.313
# still missed). Every warp (-15 % on tune) cost 1.07-1.10x on Middlebury; realtime at range 1.5 px (tune -8.8 %,
# CPU 1.03-1.04x) lost the report's missing regime (+1.8 %) and stays plain.
WEIGHTED_MEDIAN: Mapping[str, Any] = MappingProxyType(dict(median_weight_sigma=0.06, median_weight_warps="last",
                                                           median_weight_range=0.75))
# fastest, and the stream presets' base (below)
FASTEST: Mapping[str, Any] = MappingProxyType(dict(
    model="l1_tv", alpha=0.07, iterations=10, warps=4, finest_iterations=6, levels=5, finest_level=1, median_filter=5,
    gradient_scheme="interpolated", tolerance=0.0, initialisation="dis_ultrafast", init_finest_level=2,
    census_median_filter=3, census_coarse_eps=0.03, census_coarse_width=50, census_empty_contrast=0.005,
    census_delta=0.02, census_eps=0.007, census_alpha=0.36, photometric="census", **EDGE_TV,
    **dict(WEIGHTED_MEDIAN, median_weight_warps="coarse")))
PRESETS: dict[str, dict[str, Any]] = {
    "quality": dict(model="l1_tv", alpha=0.03, iterations=12, warps=10, levels=15, scale_factor=0.8,
                    level_alpha_factor=1.0, median_filter=5, gradient_scheme="interpolated", tolerance=0.0,
                    finest_level=0, initialisation="dis_fine", init_finest_level=0, **CENSUS_SCHEDULE,
                    census_iterations=8, census_finest_radius=2, census_delta=0.05, census_alpha=0.10,
                    photometric="census", **WEIGHTED_MEDIAN),
    "balanced": dict(model="l1_tv", alpha=0.035, iterations=15, warps=2, levels=15, scale_factor=0.8,
                     level_alpha_factor=1.0, median_filter=5, gradient_scheme="interpolated", tolerance=1e-3,
                     finest_level=0, initialisation="dis_fast", init_finest_level=0,
                     **dict(CENSUS_SCHEDULE, census_antialias=4), census_iterations=12, census_finest_radius=2,
                     census_finest_warps=1, census_finest_iterations=30, census_delta=0.05, census_alpha=0.10,
                     photometric="census", tv_edge_weight=0.08, **dict(WEIGHTED_MEDIAN, median_weight_range=1.5)),
    "realtime": dict(model="l1_tv", alpha=0.04, iterations=6, warps=4, finest_warps=2, finest_iterations=16,
                     levels=5, finest_level=0, median_filter=5, gradient_scheme="interpolated", tolerance=0.0,
                     initialisation="dis_ultrafast", init_finest_level=2, **CENSUS_SCHEDULE,
                     census_empty_contrast=0.002, census_delta=0.07, census_alpha=0.10, census_finest_radius=2,
                     census_finest_warps=1, census_finest_iterations=28, photometric="census", **EDGE_TV,
                     census_presmooth=0.45),
    # fastest's noise floor K is 2 (task lownoise, 2026-12-07, bench/results/suite/invariance/lownoise): the tune split
    # with its sensor_noise family (frame 2 plus noise of 3.5 / 10 grey levels) read fastest's noisy real pairs better
    # with the clean pair's lower floor, the one preset that did; K 2: real_exact_photometric -1.1 %, real_exact
    # -0.6 %, worst noise +0.0003 px; report split once: every regime within max(0.001 px, 0.5 %), low light over
    # its unchanged pairs 1.30x / 1.33x -> 1.28x / 1.31x (Middlebury / real photos). stream_fast keeps the default 3
    # fastest's primal-dual iteration is over-relaxed, rho 1.3 (pd_relaxation; 2026-12-08, the rule written first,
    # bench/results/suite/relax/): tune split geomean 0.973 over 13 regimes (real_exact -12 %, Middlebury -2.9 %; the
    # worst fine_320 +0.0006 px, bags +0.0006 px), rho 1.5-1.9 gained more but lost the bags or flat; CPU 0.92-0.98x
    # (the same iterations; interleaved, tune Middlebury / real_exact / bags). Report split once: geomean 0.967,
    # real_exact 0.3108 -> 0.2878 (DualTVL1 0.313), the worst missing +0.8 % and bags +0.5 %. quality, balanced and
    # realtime failed the same rule (the missing regime's unmasked wiper pair for all three; quality also the noisy
    # families on real images, and diverges at rho 1.9). The stream presets keep rho 1 on single pairs.
    # realtime passed round 2's rule (relax/rule2.md: missing judged with its masks, the unmasked wiper pairs being
    # garbage at any setting) at rho 1.3 (report real_exact 0.2960 -> 0.2804, low light on real photos 1.36x ->
    # 1.28x) but then missed the suite's bit-depth target the rule did not list (10/12/16 bit 1.14 / 1.13 / 1.13x its
    # 8-bit AEE, met at 1.10 / 1.08 / 1.08x with rho 1): not adopted. balanced's round-2 pick (rho 1.5) lost the
    # report split's exposure and bit_depth regimes (+43 %, +22 %)
    "fastest": dict(FASTEST, census_noise_k=2.0, pd_relaxation=1.3),
    # the paper's joint model (issue 27; docs/engine.md, "Joint model"): realtime's schedule with the images
    # eliminated (J_gamma data term); gamma and alpha chosen on the suite's noise regime, tune seeds
    "joint": dict(model="l1_tv", alpha=0.06, iterations=6, warps=4, finest_warps=2, finest_iterations=16,
                  levels=5, finest_level=0, median_filter=5, gradient_scheme="interpolated", tolerance=0.0,
                  initialisation="dis_ultrafast", init_finest_level=2, reconstruction="joint", image_gamma=0.02),
    # stream presets (issue 26, docs/engine.md "The stream mode"): fastest's fields (its census fields too, since
    # 2026-12-06) and the stream stage's: a single pair, and a stream's fallback, is
    # solved as fastest (stream_fast) or as fastest at quarter size (stream_lite) does; while the previous flow
    # predicts the next, only the finest two solved levels (stream_lite: one, a single warp of 18 over-relaxed
    # iterations, below) run, from the carried state (tuned on the suite's stream regime, tune split:
    # bench/results/suite/stream/; docs/engine.md "The stream mode"; stream_fast's coarser level 2 x 10 and its
    # finest 3 x 10 since issue 26's round 4; round 6: finest 3 x 8, a 3x3 median after a level's warps but its
    # last, the result check on ~5,000 pixels). stream_fast keeps the census EPS / alpha fastest had before task
    # feps (0.01 / 0.35: fastest's 0.007 / 0.36 lost the stream regime 1.5 %, above), so it solves a single pair as
    # fastest with those two fields, the default census_noise_k (fastest 2 since task lownoise) and the plain
    # primal-dual iteration (fastest over-relaxes at rho 1.3 since 2026-12-08; not tried on the stream presets) does.
    # Task stacc (2026-12-07): the carried duals restart from zero (stream_duals 0; the flow alone is carried) and
    # the schedule is coarse 1 x 10, finest 3 x 10: stream regime tune 320x240 0.0384 -> 0.0318 (realtime 0.0366),
    # 640x480 0.0318 -> 0.0263, at 0.98-1.02x the CPU per frame (bench/results/suite/stream/stacc/summary.md); then, for
    # time (the lead, same day, tune split): coarse 1 x 6, finest 2 x 14, 0.91x that CPU at 320x240 / 0.92x at
    # 640x480 for tune 0.0324 / 0.0273 (realtime 0.0366 / 0.0351), bags +1.7 %
    # (bench/results/suite/stream/lead_s25/summary.md)
    "stream_fast": dict(FASTEST, stream_levels=2, stream_warps=1, stream_iterations=6, stream_finest_warps=2,
                        stream_finest_iterations=14, stream_inner_median=3, stream_check_samples=5000,
                        stream_duals=0.0, census_eps=0.01, census_alpha=0.35),
    # stream_lite (task litezd, 2026-12-07, bench/results/suite/stream/litezd/summary.md): fastest's census fields
    # at quarter size with census DELTA 0.003 (fastest 0.02), the duals restarted (stream_duals 0) and one warp of
    # 34 iterations on its one stream level (was grey values, carried duals, 8 x 10): tune 320x240 0.0481 -> 0.0481,
    # 640x480 0.0417 -> 0.0392 (DIS medium 0.0508 / 0.0438), bags -1.4 %, at 0.66x / 0.58x the CPU per frame;
    # report split 0.0504 / 0.0421 (DIS medium 0.0520 / 0.0481); objects lose (report 0.105 -> 0.141 at 320x240).
    # Its single pairs and fallbacks compare census signatures too (report 320x240 0.087 -> 0.058).
    # The result check samples ~5,000 pixels, as stream_fast's (the lead, same day: tune 0.89x the CPU at 320x240,
    # report split the same flows and AEE at 0.86x / 0.95x the wall time; bench/results/suite/stream/litezd/checks/)
    # Its refinement's primal-dual iteration is over-relaxed (stream_relaxation 1.9; task pdrelax and the lead,
    # 2026-12-07, bench/results/suite/stream/pdrelax/summary.md): 18 iterations reach 34 plain ones' AEE (tune
    # 320x240 0.0481 -> 0.0477, report 0.0504 -> 0.0501 / 0.0421 -> 0.0422, bags +0.2 %, held-out +0.4 %) at
    # 0.90-0.92x the CPU per frame. The task's rule picked rho 1.7 with the step length on the duals (tau / 4,
    # sigma x 4: a field retired since, git show 99f0f54) and 10 iterations, 0.85x the CPU, but it lost the
    # held-out split 12 % (shake, wave)
    "stream_lite": dict(FASTEST, finest_level=2, stream_levels=1, stream_warps=1, stream_iterations=18,
                        stream_relaxation=1.9, stream_duals=0.0, census_delta=0.003, stream_check_samples=5000),
}

# The general-purpose presets, in order of cost: what the suite judges against the peers on every regime. The
# others serve one kind of input: `joint` noisy frames (docs/engine.md, "Joint model"), `stream_fast` and
# `stream_lite` the pairs of a stream (single pairs as `fastest`; docs/engine.md, "The stream mode").
GENERAL_PRESETS = ("quality", "balanced", "realtime", "fastest")
