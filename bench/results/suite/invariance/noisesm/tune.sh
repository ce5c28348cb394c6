#!/bin/sh
# tune.sh OUT.json --method ... : the tune split, AEE only, task noisesm's regimes (run from the worktree root)
OUT=$1; shift
export PYTHONPATH=/work/wt/noisesm NUMBA_CACHE_DIR=/work/wt/noisesm/.numba_cache ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST \
  RMW_IMPLEMENTATION=rmw_fastrtps_cpp ROS_DOMAIN_ID=87
exec nice -n 19 /work/main/.venv-bench/bin/python -m bench.suite --split tune --peers none --repeats 0 --slow-repeats 0 \
  --regimes noise,fine_320,bit_depth,low_contrast,middlebury,real_exact,photometric,photometric_real,real_exact_photometric,bags \
  --out "$OUT" "$@"
