#!/bin/bash
# pass 6 (tune split, quick): the synthetic regimes the window could move (noise, fine textures, flat, low contrast)
cd /work/wt-censwin
export NUMBA_CACHE_DIR=/work/wt-censwin/.numba_cache ROS_DOMAIN_ID=61 ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST RMW_IMPLEMENTATION=rmw_fastrtps_cpp PYTHONPATH=$PWD
D=bench/results/suite/invariance/censwin/runs
M="--method quality_census=quality,photometric=census,alpha=0.045,threads=1 --method quality_census_f2=quality,photometric=census,alpha=0.045,census_finest_radius=2,threads=1 --method realtime_census=realtime,photometric=census,threads=1 --method realtime_census_f2=realtime,photometric=census,census_finest_radius=2,threads=1"
nice -n 5 /work/main/.venv-bench/bin/python -m bench.suite --split tune --quick --regimes noise,fine_320,fine_640,flat,low_contrast --peers none --repeats 1 $M --out $D/p6_synth.json > $D/p6_synth.log 2>&1
