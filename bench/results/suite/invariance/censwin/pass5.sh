#!/bin/bash
# pass 5 (tune split; Middlebury and bags fixed data): the FlowConfig field census_finest_radius 2 (this branch),
# quality and realtime (reproducing levels.py's fine2 rule), fastest beside today's fastest census
cd /work/wt-censwin
export NUMBA_CACHE_DIR=/work/wt-censwin/.numba_cache ROS_DOMAIN_ID=61 ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST RMW_IMPLEMENTATION=rmw_fastrtps_cpp PYTHONPATH=$PWD
D=bench/results/suite/invariance/censwin/runs
M="--method quality_census_f2=quality,photometric=census,alpha=0.045,census_finest_radius=2,threads=1 --method realtime_census_f2=realtime,photometric=census,census_finest_radius=2,threads=1 --method fastest_census=fastest,photometric=census,threads=1 --method fastest_census_f2=fastest,photometric=census,census_finest_radius=2,threads=1"
nice -n 5 /work/main/.venv-bench/bin/python -m bench.suite --split tune --regimes middlebury,bags --peers none --repeats 1 $M --out $D/p5_fixed.json > $D/p5_fixed.log 2>&1 &
nice -n 5 /work/main/.venv-bench/bin/python -m bench.suite --split tune --quick --regimes real_exact,real_exact_photometric,photometric_real,photometric --peers none --repeats 1 $M --out $D/p5_tune.json > $D/p5_tune.log 2>&1 &
wait
