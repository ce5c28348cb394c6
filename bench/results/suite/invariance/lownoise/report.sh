#!/bin/sh
# report.sh OUT.json --method ... : the report split, AEE only, once (task lownoise; run from the worktree root)
OUT=$1; shift
export PYTHONPATH=/work/wt/lownoise NUMBA_CACHE_DIR=/work/wt/lownoise/.numba_cache ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST \
  RMW_IMPLEMENTATION=rmw_fastrtps_cpp ROS_DOMAIN_ID=89
exec nice -n 19 /work/main/.venv-bench/bin/python -m bench.suite --split report --peers none --repeats 0 --slow-repeats 0 \
  --regimes middlebury,real_exact,large,bags,fine_320,fine_640,noise,bit_depth,photometric,photometric_real,real_exact_photometric,missing \
  --out "$OUT" "$@"
