#!/bin/bash
# Tune split: census_noise_k in {1.5, 2, 2.5, 3, 4, 6} per preset (issue 25, noisek). AEE only (--repeats 0:
# no timed runs; the suite writes .json/.md, then its png fails on the empty times -- harmless).
# usage: tune.sh PRESET LETTER OUT REGIMES
P=$1; L=$2; OUT=$3; REG=$4
M=()
for k in 1.5 2 2.5 3 4 6; do M+=(--method "$L${k/./}=$P,census_noise_k=$k"); done
PYTHONPATH=$PWD /work/main/.venv-bench/bin/python -m bench.suite --split tune --peers none --repeats 0 --slow-repeats 0 \
  --regimes "$REG" "${M[@]}" --out "$OUT"
