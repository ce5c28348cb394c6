#!/bin/bash
# The report split, once: balanced (grey values) against the tune split's choice a3f30 (task balcens2)
cd "$(dirname "$0")/../../../../.." || exit 1
REG=middlebury,real_exact,bags,large,noise,photometric,photometric_real,real_exact_photometric,fine_320,fine_640,bit_depth,low_contrast,flat,exposure,missing
C=balanced,photometric=census,census_delta=0.05,census_alpha=0.10,census_coarse_eps=0.03,census_coarse_width=50,census_finest_radius=2,census_antialias=3,census_finest_warps=1,census_finest_iterations=30
PYTHONPATH=$PWD NUMBA_CACHE_DIR=$PWD/.numba_cache ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST RMW_IMPLEMENTATION=rmw_fastrtps_cpp \
ROS_DOMAIN_ID=82 nice -n 5 /work/main/.venv-bench/bin/python -m bench.suite --split report --peers none --repeats 0 \
  --slow-repeats 0 --regimes $REG --method bal=balanced --method a3f30=$C --out bench/results/suite/invariance/balcens2/report.json
