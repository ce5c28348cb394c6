#!/bin/bash
# Interleaved A/B of lin_bench.py: main (its worktree /work/wt-linearise5-main) against each variant of
# numba_warp.py in variants/ (copied over this worktree's file for its run, restored after); ROUNDS rounds,
# a fresh process per run; each line: side, load average, medians (ms) over 40 calls.
ROUNDS=${1:-5}
B=/work/wt-linearise5; A=/work/wt-linearise5-main; R=$B/bench/results/linearise5
cp $B/flow_node/core/numba_warp.py /tmp/lin5_orig.py
for r in $(seq $ROUNDS); do
  echo -n "main $(cut -d' ' -f1-3 /proc/loadavg) "
  (cd $A && NUMBA_CACHE_DIR=$A/.numba_cache PYTHONPATH=$A /work/main/.venv/bin/python $R/lin_bench.py 40)
  for v in split branchfree colfirst; do
    cp $R/variants/${v}_numba_warp.py.txt $B/flow_node/core/numba_warp.py
    echo -n "$v $(cut -d' ' -f1-3 /proc/loadavg) "
    (cd $B && NUMBA_CACHE_DIR=$B/.numba_cache_$v PYTHONPATH=$B /work/main/.venv/bin/python $R/lin_bench.py 40)
  done
done
cp /tmp/lin5_orig.py $B/flow_node/core/numba_warp.py
