#!/bin/bash
# run_report.sh's three report runs again after NOISE_STRIDE 3 -> 4 (the stride-3 results: commit e9ee5eb); overwrites report_*.
set -e
D=bench/results/suite/invariance/lowlight2
PY="nice env PYTHONPATH=$PWD /work/main/.venv-bench/bin/python -m bench.suite"
REP="--split report --regimes photometric_real,real_exact_photometric,real_exact,photometric,middlebury,bags,large --peers none --repeats 1"
$PY $REP --method realtime_census=realtime,photometric=census --method realtime_census_k0=realtime,photometric=census,census_noise_k=0 \
  --out $D/report_realtime.json > $D/report_realtime.log 2>&1
$PY $REP --method fastest_census=fastest,photometric=census --method fastest_census_k0=fastest,photometric=census,census_noise_k=0 \
  --out $D/report_fastest.json > $D/report_fastest.log 2>&1
$PY $REP --method quality_census=quality,photometric=census,alpha=0.045 \
  --method quality_census_k0=quality,photometric=census,alpha=0.045,census_noise_k=0 \
  --out $D/report_quality.json > $D/report_quality.log 2>&1
