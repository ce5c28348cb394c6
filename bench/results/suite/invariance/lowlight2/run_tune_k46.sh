#!/bin/bash
# added after run_tune.sh's realtime run (K = 3 was still improving real_exact): realtime K = 4, 6 on the same tune regimes
D=bench/results/suite/invariance/lowlight2
nice env PYTHONPATH=$PWD /work/main/.venv-bench/bin/python -m bench.suite --split tune --regimes noise,photometric_real,real_exact_photometric,middlebury \
  --peers none --repeats 1 --method rt_k4=realtime,photometric=census,census_noise_k=4 --method rt_k6=realtime,photometric=census,census_noise_k=6 \
  --out $D/tune_realtime_k46.json > $D/tune_realtime_k46.log 2>&1
