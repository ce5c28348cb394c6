#!/bin/bash
# The tune-split passes on the numba kernels (mean AEE in runs/<pass>_*.json; tables: tables.py, fam.py).
# Usage: bash tune.sh PASS   (PASS = p2 | p3 | p5 | p6 | p7; p7: after the far noise floor, commit a2e9b88)
# p2 / p3 ran on the branch's intermediate tree, whose FlowConfig field census_radius set the radius on every
# level; it was replaced by census_finest_radius (finest level only), so they no longer parse. study.py's numpy
# variant r2 reproduces p2's radius-2 rows (Middlebury 0.304 / 0.396, bags 0.065 / 0.075, real_exact 0.243 /
# 0.378, to 3 decimals); p3 ran with the field's choices widened to (1, 2, 3) for the run (study.py r3: the same
# signature, not re-run). levels.py (fine2 / coarse2) is its own script.
cd /work/wt-censwin
export NUMBA_CACHE_DIR=/work/wt-censwin/.numba_cache ROS_DOMAIN_ID=61 ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST RMW_IMPLEMENTATION=rmw_fastrtps_cpp PYTHONPATH=$PWD
D=bench/results/suite/invariance/censwin/runs
Q="quality,photometric=census,alpha=0.045,threads=1"
R="realtime,photometric=census,threads=1"
F="fastest,photometric=census,threads=1"
suite() {  # OUT REGIMES [--quick] METHODS...: one tune-split suite run, no peers
    local out=$1 regimes=$2; shift 2
    nice -n 5 /work/main/.venv-bench/bin/python -m bench.suite --split tune --regimes "$regimes" --peers none \
        --repeats 1 "$@" --out "$D/$out.json" > "$D/$out.log" 2>&1
}
fixed_and_tune() {  # PASS METHODS...: Middlebury and bags (every pair) beside the quick photometric regimes
    local p=$1; shift
    suite "${p}_fixed" middlebury,bags "$@" &
    suite "${p}_tune" real_exact,real_exact_photometric,photometric_real,photometric --quick "$@" &
    wait
}
case $1 in
p2) fixed_and_tune p2 --method quality_census=$Q --method quality_census_r2=$Q,census_radius=2 \
        --method realtime_census=$R --method realtime_census_r2=$R,census_radius=2 ;;
p3) fixed_and_tune p3 --method quality_census_r3=$Q,census_radius=3 --method realtime_census_r3=$R,census_radius=3 ;;
p5) fixed_and_tune p5 --method quality_census_f2=$Q,census_finest_radius=2 \
        --method realtime_census_f2=$R,census_finest_radius=2 --method fastest_census=$F \
        --method fastest_census_f2=$F,census_finest_radius=2 ;;
p6) suite p6_synth noise,fine_320,fine_640,flat,low_contrast --quick --method quality_census=$Q \
        --method quality_census_f2=$Q,census_finest_radius=2 --method realtime_census=$R \
        --method realtime_census_f2=$R,census_finest_radius=2 ;;
p7) suite p7_floor noise,low_contrast,bit_depth,real_exact_photometric,photometric --quick --method quality_census=$Q \
        --method quality_census_f2=$Q,census_finest_radius=2 --method realtime_census=$R \
        --method realtime_census_f2=$R,census_finest_radius=2 ;;
esac
