#!/bin/bash
# After K = 2 was chosen on the tune split (run_tune.sh, run_tune_k46.sh; FlowConfig.census_noise_k default 2):
# fastest on the tune split as a check, then ONE report-split run per census preset, each with the new default
# (K = 2, symmetric presmoothing) and K = 0 (symmetric presmoothing only) in the same run. From the worktree root.
# The committed report_* files are these three report runs made again after NOISE_STRIDE 3 -> 4 (stride 3: e9ee5eb).
set -e
D=bench/results/suite/invariance/lowlight2
PY="nice env PYTHONPATH=$PWD /work/main/.venv-bench/bin/python -m bench.suite"
$PY --split tune --regimes noise,photometric_real,real_exact_photometric,middlebury --peers none --repeats 1 \
  --method fastest_k0=fastest,photometric=census,census_noise_k=0 --method fastest_k2=fastest,photometric=census,census_noise_k=2 \
  --out $D/tune_fastest.json > $D/tune_fastest.log 2>&1
REP="--split report --regimes photometric_real,real_exact_photometric,real_exact,photometric,middlebury,bags,large --peers none --repeats 1"
$PY $REP --method realtime_census=realtime,photometric=census --method realtime_census_k0=realtime,photometric=census,census_noise_k=0 \
  --out $D/report_realtime.json > $D/report_realtime.log 2>&1
$PY $REP --method fastest_census=fastest,photometric=census --method fastest_census_k0=fastest,photometric=census,census_noise_k=0 \
  --out $D/report_fastest.json > $D/report_fastest.log 2>&1
$PY $REP --method quality_census=quality,photometric=census,alpha=0.045 \
  --method quality_census_k0=quality,photometric=census,alpha=0.045,census_noise_k=0 \
  --out $D/report_quality.json > $D/report_quality.log 2>&1
