#!/bin/bash
# stream_fast (fastest's census fields) with census_noise_k 2 and 3, the stream regime's tune split, 320x240
PYTHONPATH=$PWD /work/main/.venv-bench/bin/python -m bench.suite.streams --split tune --size 320x240 \
  --method sf2=stream_fast,census_noise_k=2 --method sf3=stream_fast,census_noise_k=3 --out bench/results/suite/invariance/noisek/stream
