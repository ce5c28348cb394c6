#!/bin/bash
# Report split, once, for a preset whose tune rule moved K: K = 2 (today) against the new K, same run.
# usage: report.sh PRESET LETTER NEWK OUT
P=$1; L=$2; K=$3; OUT=$4
PYTHONPATH=$PWD /work/main/.venv-bench/bin/python -m bench.suite --split report --peers none --repeats 0 --slow-repeats 0 \
  --regimes middlebury,real_exact,bags,large,noise,photometric,photometric_real,real_exact_photometric \
  --method "${L}2=$P,census_noise_k=2" --method "$L${K/./}=$P,census_noise_k=$K" --out "$OUT"
