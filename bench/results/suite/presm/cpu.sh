#!/bin/sh
# cpu.sh OUT.json REPEATS --method ... : CPU clock (process time), one thread per method, tune split, interleaved
# (task presm, after task noisesm's cpu.sh; run from the worktree root)
OUT=$1; REP=$2; shift 2
export PYTHONPATH=/work/wt/presm NUMBA_CACHE_DIR=/work/wt/presm/.numba_cache ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST \
  RMW_IMPLEMENTATION=rmw_fastrtps_cpp ROS_DOMAIN_ID=88
cat /proc/loadavg
nice -n 19 /work/main/.venv-bench/bin/python -m bench.suite --split tune --peers none --clock cpu --repeats "$REP" \
  --slow-repeats "$REP" --regimes middlebury,fine_320,bags --out "$OUT" "$@"
cat /proc/loadavg
