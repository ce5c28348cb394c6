#!/bin/bash
# usage: tune.sh OUT.json --method ... (tune split, AEE only, issue 25 task balcens2; restored for balcens3's regimes)
cd "$(dirname "$0")/../../../../.." || exit 1
OUT=$1; shift
REG=middlebury,real_exact,photometric_real,fine_320,fine_640,flat,noise,low_contrast,bit_depth,exposure,large,bags,missing
PYTHONPATH=$PWD NUMBA_CACHE_DIR=$PWD/.numba_cache ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST RMW_IMPLEMENTATION=rmw_fastrtps_cpp \
ROS_DOMAIN_ID=84 nice -n 5 /work/main/.venv-bench/bin/python -m bench.suite --split tune --peers none --repeats 0 \
  --slow-repeats 0 --regimes $REG --out "$OUT" "$@"
