#!/bin/sh
# tune.sh OUT.json --method ... : the tune split, AEE only, task presm's regimes (run from the worktree root)
OUT=$1; shift
export PYTHONPATH=/work/wt/presm NUMBA_CACHE_DIR=/work/wt/presm/.numba_cache ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST \
  RMW_IMPLEMENTATION=rmw_fastrtps_cpp ROS_DOMAIN_ID=88
exec nice -n 19 /work/main/.venv-bench/bin/python -m bench.suite --split tune --peers none --repeats 0 --slow-repeats 0 \
  --regimes noise,fine_320,fine_640,bit_depth,low_contrast,flat,middlebury,real_exact,photometric,photometric_real,real_exact_photometric,bags,missing \
  --out "$OUT" "$@"
