#!/bin/bash
# report split, once: today's census beside census_finest_radius 2 (quality at alpha 0.045, realtime), same run,
# in two processes (regimes split between them); fastest not run (radius 2 lost on its tune split)
cd /work/wt-censwin
export NUMBA_CACHE_DIR=/work/wt-censwin/.numba_cache ROS_DOMAIN_ID=61 ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST RMW_IMPLEMENTATION=rmw_fastrtps_cpp PYTHONPATH=$PWD
D=bench/results/suite/invariance/censwin
M="--method quality_census=quality,photometric=census,alpha=0.045 --method quality_census_f2=quality,photometric=census,alpha=0.045,census_finest_radius=2 --method realtime_census=realtime,photometric=census --method realtime_census_f2=realtime,photometric=census,census_finest_radius=2"
nice -n 5 /work/main/.venv-bench/bin/python -m bench.suite --split report --regimes photometric_real,middlebury,bags --peers none --repeats 1 $M --out $D/report_a.json > $D/runs/report_a.log 2>&1 &
nice -n 5 /work/main/.venv-bench/bin/python -m bench.suite --split report --regimes real_exact_photometric,real_exact,photometric,large --peers none --repeats 1 $M --out $D/report_b.json > $D/runs/report_b.log 2>&1 &
wait
