#!/bin/bash
# A/B stream_fast per-frame time: f0ff185 (12-05's 0.94x reading) vs main, alternating, same hour
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST RMW_IMPLEMENTATION=rmw_fastrtps_cpp ROS_DOMAIN_ID=92
for r in 0 1 2; do
  for t in old new; do
    if [ $t = old ]; then d=/tmp/sd-old; else d=/work/main; fi
    (cd $d && PYTHONPATH=$d NUMBA_CACHE_DIR=$d/.nc_sd /work/main/.venv-bench/bin/python -m bench.suite.streams --split report --size 320x240 --method stream_fast=stream_fast --out /tmp/lead/sd/${t}_$r > /dev/null 2>&1)
    echo "round $r $t $(uptime | sed 's/.*average://') $(grep '^| stream_fast\|^| dis_medium' /tmp/lead/sd/${t}_$r/report_320x240.md | tr '\n' ' ')"
  done
done
