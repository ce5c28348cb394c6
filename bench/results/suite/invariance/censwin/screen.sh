#!/bin/bash
# screening (pass 1b): the other windows on Middlebury (8 pairs), bags (29) and real_exact (tune, quick) only
cd /work/wt-censwin
export NUMBA_CACHE_DIR=/work/wt-censwin/.numba_cache ROS_DOMAIN_ID=61 ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST RMW_IMPLEMENTATION=rmw_fastrtps_cpp PYTHONPATH=$PWD
D=bench/results/suite/invariance/censwin
for v in "$@"; do nice -n 5 /work/main/.venv-bench/bin/python $D/study.py $v $D/runs/s_$v.json middlebury,bags,real_exact --quick > $D/runs/s_$v.log 2>&1; done
