#!/bin/sh
# tune.sh OUT.json --method ... : the tune split, AEE only, task lownoise's regimes (run from the worktree root)
OUT=$1; shift
export PYTHONPATH=/work/wt/lownoise NUMBA_CACHE_DIR=/work/wt/lownoise/.numba_cache ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST \
  RMW_IMPLEMENTATION=rmw_fastrtps_cpp ROS_DOMAIN_ID=89
exec nice -n 19 /work/main/.venv-bench/bin/python -m bench.suite --split tune --peers none --repeats 0 --slow-repeats 0 \
  --regimes noise,fine_320,low_contrast,middlebury,real_exact,photometric,photometric_real,real_exact_photometric,bags,missing,bit_depth \
  --out "$OUT" "$@"
