#!/bin/bash
# report split, second run (after the noise floor for the far signature, commit "Census noise floor for the far
# signature"): census_finest_radius 2 only (today's census rows are report.sh's: the change leaves radius 1 alone)
cd /work/wt-censwin
export NUMBA_CACHE_DIR=/work/wt-censwin/.numba_cache ROS_DOMAIN_ID=61 ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST RMW_IMPLEMENTATION=rmw_fastrtps_cpp PYTHONPATH=$PWD
D=bench/results/suite/invariance/censwin
M="--method quality_census_f2=quality,photometric=census,alpha=0.045,census_finest_radius=2 --method realtime_census_f2=realtime,photometric=census,census_finest_radius=2"
nice -n 5 /work/main/.venv-bench/bin/python -m bench.suite --split report --regimes photometric_real,middlebury,bags --peers none --repeats 1 $M --out $D/report2_a.json > $D/runs/report2_a.log 2>&1 &
nice -n 5 /work/main/.venv-bench/bin/python -m bench.suite --split report --regimes real_exact_photometric,real_exact,photometric,large --peers none --repeats 1 $M --out $D/report2_b.json > $D/runs/report2_b.log 2>&1 &
wait
