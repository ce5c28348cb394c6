#!/bin/bash
# pass 3 (tune split; Middlebury and bags fixed data): census_radius 3 (run with the config's choices widened to
# (1, 2, 3) for the run only; the kernels take any radius, checked against the numpy reference to 1e-6)
# NOTE: run on the branch's intermediate tree, whose FlowConfig field census_radius set the radius on every
# level (census_radius 3 on every level); that field was replaced by census_finest_radius (finest level only) and
# these commands no longer parse. study.py's numpy variant r3 is the same signature (not re-run).
cd /work/wt-censwin
export NUMBA_CACHE_DIR=/work/wt-censwin/.numba_cache ROS_DOMAIN_ID=61 ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST RMW_IMPLEMENTATION=rmw_fastrtps_cpp PYTHONPATH=$PWD
D=bench/results/suite/invariance/censwin/runs
M="--method quality_census_r3=quality,photometric=census,alpha=0.045,census_radius=3,threads=1 --method realtime_census_r3=realtime,photometric=census,census_radius=3,threads=1"
nice -n 5 /work/main/.venv-bench/bin/python -m bench.suite --split tune --regimes middlebury,bags --peers none --repeats 1 $M --out $D/p3_fixed.json > $D/p3_fixed.log 2>&1
nice -n 5 /work/main/.venv-bench/bin/python -m bench.suite --split tune --quick --regimes real_exact,real_exact_photometric,photometric_real,photometric --peers none --repeats 1 $M --out $D/p3_tune.json > $D/p3_tune.log 2>&1
