#!/bin/bash
# usage: cpu.sh OUT.json REGIMES REPEATS --method ... (CPU clock, one thread, no peers)
cd "$(dirname "$0")/../../../../.." || exit 1
OUT=$1; REG=$2; REP=$3; shift 3
cat /proc/loadavg
PYTHONPATH=$PWD NUMBA_CACHE_DIR=$PWD/.numba_cache ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST RMW_IMPLEMENTATION=rmw_fastrtps_cpp \
ROS_DOMAIN_ID=84 nice -n 5 /work/main/.venv-bench/bin/python -m bench.suite --peers none --clock cpu --repeats $REP \
  --slow-repeats $REP --regimes $REG --out "$OUT" "$@"
cat /proc/loadavg
