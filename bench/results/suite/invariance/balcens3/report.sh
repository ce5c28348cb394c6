#!/bin/bash
# The report split, once: balanced (grey values, no weight) against the tune split's choice a4f30w08i12 (task balcens3)
cd "$(dirname "$0")/../../../../.." || exit 1
REG=middlebury,real_exact,bags,large,noise,photometric,photometric_real,real_exact_photometric,fine_320,fine_640,bit_depth,missing
C=balanced,photometric=census,census_delta=0.05,census_alpha=0.10,census_coarse_eps=0.03,census_coarse_width=50,census_finest_radius=2,census_antialias=4,census_finest_warps=1,census_finest_iterations=30,tv_edge_weight=0.08,census_iterations=12
PYTHONPATH=$PWD NUMBA_CACHE_DIR=$PWD/.numba_cache ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST RMW_IMPLEMENTATION=rmw_fastrtps_cpp \
ROS_DOMAIN_ID=84 nice -n 5 /work/main/.venv-bench/bin/python -m bench.suite --split report --peers none --repeats 0 \
  --slow-repeats 0 --regimes $REG --method bal=balanced --method a4f30w08i12=$C --out bench/results/suite/invariance/balcens3/report.json
