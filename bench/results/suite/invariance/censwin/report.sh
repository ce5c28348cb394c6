#!/bin/bash
# Report split, once: `bash report.sh first` -- today's census beside census_finest_radius 2 (quality at alpha
# 0.045, realtime) in the same run (report_a/b.json; fastest not run: radius 2 lost on its tune split);
# `bash report.sh second` -- after the far noise floor (commit a2e9b88), the ring alone (report2_a/b.json; today's
# census does not change). Two processes each, the regimes split between them.
cd /work/wt-censwin
export NUMBA_CACHE_DIR=/work/wt-censwin/.numba_cache ROS_DOMAIN_ID=61 ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST RMW_IMPLEMENTATION=rmw_fastrtps_cpp PYTHONPATH=$PWD
D=bench/results/suite/invariance/censwin
Q="quality,photometric=census,alpha=0.045"
R="realtime,photometric=census"
RING="--method quality_census_f2=$Q,census_finest_radius=2 --method realtime_census_f2=$R,census_finest_radius=2"
if [ "$1" = first ]; then out=report; M="--method quality_census=$Q --method realtime_census=$R $RING"
else out=report2; M="$RING"; fi
run() {  # SUFFIX REGIMES
    nice -n 5 /work/main/.venv-bench/bin/python -m bench.suite --split report --regimes "$2" --peers none \
        --repeats 1 $M --out "$D/${out}_$1.json" > "$D/runs/${out}_$1.log" 2>&1
}
run a photometric_real,middlebury,bags &
run b real_exact_photometric,real_exact,photometric,large &
wait
