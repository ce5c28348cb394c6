#!/bin/sh
# The suite runs of task cube (issue 25), from the worktree root with the bench venv (PATH), the tree's flow_node
# on PYTHONPATH; AEE is deterministic. NAME: the tree's label (main: the base commit's tree; equalised: the first
# step, initialise.equalised only; final: equalised input and census fusion cost).
set -e
NAME=${1:?label}
M="--method quality_census=quality,photometric=census,alpha=0.045 --method realtime_census=realtime,photometric=census --method fastest_census=fastest,photometric=census --peers none --repeats 1"
R=/work/wt-cube/bench/results/suite/invariance/cube
nice -n 5 python -m bench.suite --split tune --regimes photometric_real,real_exact,middlebury,bags $M --out $R/tune_$NAME.json
[ "$NAME" = main ] || nice -n 5 python -m bench.suite --split report --regimes large,middlebury,bags,real_exact,photometric_real $M --out $R/report_$NAME.json
nice -n 5 python $R/large_gamma.py.txt > $R/large_gamma_$NAME.md
