#!/bin/bash
# K selection on the tune split (low light held out: it is a report-only family). From the worktree root.
set -e
D=bench/results/suite/invariance/lowlight2
R="--split tune --regimes noise,photometric_real,real_exact_photometric,middlebury --peers none --repeats 1"
PY="nice env PYTHONPATH=$PWD /work/main/.venv-bench/bin/python -m bench.suite"
$PY $R --method rt_k0=realtime,photometric=census,census_noise_k=0 --method rt_k1=realtime,photometric=census,census_noise_k=1 \
  --method rt_k2=realtime,photometric=census,census_noise_k=2 --method rt_k3=realtime,photometric=census,census_noise_k=3 \
  --out $D/tune_realtime.json > $D/tune_realtime.log 2>&1
$PY $R --method q_k0=quality,photometric=census,alpha=0.045,census_noise_k=0 --method q_k1=quality,photometric=census,alpha=0.045,census_noise_k=1 \
  --method q_k2=quality,photometric=census,alpha=0.045,census_noise_k=2 --method q_k3=quality,photometric=census,alpha=0.045,census_noise_k=3 \
  --out $D/tune_quality.json > $D/tune_quality.log 2>&1
