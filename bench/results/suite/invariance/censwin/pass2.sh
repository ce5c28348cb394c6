#!/bin/bash
# pass 2 (tune split; Middlebury and bags are fixed data): today's census against census_radius 2, with this
# branch's numba kernels (the numpy study's hybrid was too slow for the photometric regimes at load ~10)
# NOTE: run on the branch's intermediate tree, whose FlowConfig field census_radius set the radius on every
# level (census_radius 2 on every level); that field was replaced by census_finest_radius (finest level only) and
# these commands no longer parse. study.py's numpy variants r2 reproduce the radius-2 rows (Middlebury 0.304 /
# 0.396, bags 0.065 / 0.075, real_exact 0.243 / 0.378: the same to 3 decimals).
cd /work/wt-censwin
export NUMBA_CACHE_DIR=/work/wt-censwin/.numba_cache ROS_DOMAIN_ID=61 ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST RMW_IMPLEMENTATION=rmw_fastrtps_cpp PYTHONPATH=$PWD
D=bench/results/suite/invariance/censwin/runs
M="--method quality_census=quality,photometric=census,alpha=0.045,threads=1 --method quality_census_r2=quality,photometric=census,alpha=0.045,census_radius=2,threads=1 --method realtime_census=realtime,photometric=census,threads=1 --method realtime_census_r2=realtime,photometric=census,census_radius=2,threads=1"
nice -n 5 /work/main/.venv-bench/bin/python -m bench.suite --split tune --regimes middlebury,bags --peers none --repeats 1 $M --out $D/p2_fixed.json > $D/p2_fixed.log 2>&1 &
nice -n 5 /work/main/.venv-bench/bin/python -m bench.suite --split tune --quick --regimes real_exact,real_exact_photometric,photometric_real,photometric --peers none --repeats 1 $M --out $D/p2_tune.json > $D/p2_tune.log 2>&1 &
wait
