#!/bin/bash
# interleaved A/B: main (flow_node of /work/main, this branch's bench) and fusecens, one round per process
export ROS_DOMAIN_ID=71 ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST RMW_IMPLEMENTATION=rmw_fastrtps_cpp
OUT=/work/wt-fusecens/bench/results/census_cost/fusecens/ab
for r in $(seq 1 12); do
  for tree in main fusecens; do
    if [ $tree = main ]; then PP=/tmp/fusecens_ab_main; NC=/tmp/fusecens_main_cache; else PP=/work/wt-fusecens; NC=/work/wt-fusecens/.numba_cache; fi
    (cd /tmp && NUMBA_CACHE_DIR=$NC PYTHONPATH=$PP /work/main/.venv/bin/python -m bench.census_cost --data large \
      --presets realtime,fastest --rounds 1 --clock cpu --out $OUT/${tree}_r$r) > $OUT/${tree}_r$r.log 2>&1
    echo "$tree $r $(date -u +%H:%M:%S) $(cat /proc/loadavg)"
  done
done
