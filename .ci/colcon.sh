#!/usr/bin/env bash
# CI step: the package as a ROS 2 user builds and tests it. The real ros2 CLI, colcon, launch and
# launch_testing (../shared/tools/ros2-toolchain, ~1-2 min) stand in for a system Jazzy; the package is built
# in a colcon workspace and `colcon test` runs the suite with launch_testing's pytest plugin loaded, as in every
# ROS install. Then a smoke test of the installed package from the workspace root (README, "ROS 2 workspace").
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
tool=$root/../shared/tools/ros2-toolchain
if [ ! -x "$tool" ]; then
  if [ "${CI:-}" = true ]; then echo "colcon step: $tool not found"; exit 1; fi
  echo "colcon step skipped: no $tool (it is only beside CI's and the developers' clones)"; exit 0
fi
# outside the clone: the workspace links the clone in as src/flow_node, and colcon test runs pytest there
work=${FLOW_NODE_COLCON_WORK:-$(dirname "$root")/.flow_node-colcon-$(basename "$root")}
rm -rf "$work" && mkdir -p "$work"
grep -vE '^(pytest|ruff)==' requirements.txt > "$work/runtime-requirements.txt"  # the toolchain pins pytest<8
echo "== ros2 toolchain (real ros2 CLI, colcon, launch_testing) into $work/r2"
"$tool" "$work/r2" "$work/runtime-requirements.txt" > "$work/toolchain.log" 2>&1 \
  || { tail -n 30 "$work/toolchain.log"; exit 1; }
mkdir -p "$work/ws/src" && ln -s "$root" "$work/ws/src/flow_node"
cd "$work/ws"
set +u  # colcon's setup files are not `set -u` safe
source "$work/r2/activate.sh"
echo "== colcon build"
colcon build --packages-select flow_node
source install/setup.bash
set -u
echo "== installed package, from the workspace root"
bash "$root/.ci/ros2_smoke.sh"
echo "== colcon test (launch_testing plugin loaded)"
colcon test --packages-select flow_node --event-handlers console_direct+ --pytest-args -q
colcon test-result --verbose
