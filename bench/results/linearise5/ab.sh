#!/bin/bash
# Interleaved A/B of lin_bench.py: A = main worktree, B = this branch; ROUNDS rounds, each a fresh process per side.
ROUNDS=${1:-7}
B=/work/wt-linearise5; A=/work/wt-linearise5-main
for r in $(seq $ROUNDS); do
  for side in A B; do
    d=${!side}
    echo -n "$side $(cut -d' ' -f1-3 /proc/loadavg) "
    (cd $d && NUMBA_CACHE_DIR=$d/.numba_cache PYTHONPATH=$d /work/main/.venv/bin/python $B/bench/results/linearise5/lin_bench.py 40)
  done
done
