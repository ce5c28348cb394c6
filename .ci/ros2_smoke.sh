#!/usr/bin/env bash
# The installed package through the real ros2 CLI, from a colcon workspace root with install/setup.bash
# sourced (called by .ci/colcon.sh). Each check fails the step with what it saw.
set -uo pipefail
export ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-77}
share=$(ros2 pkg prefix flow_node)/share/flow_node
bag=$(dirname "$(readlink -f "$0")")/../bags/rotation
log=$(mktemp -d)
fail() { echo "ros2 smoke: FAILED: $*"; exit 1; }
groups=()
cleanup() { for g in "${groups[@]}"; do kill -KILL -- "-$g" 2>/dev/null; done; ros2 daemon stop > /dev/null 2>&1; rm -rf "$log"; }
trap cleanup EXIT
start() {  # start NAME CMD...: in its own process group, output to $log/NAME
  local name=$1; shift
  setsid "$@" > "$log/$name" 2>&1 &
  eval "pid_$name=$!"
  groups+=("$!")
}
stop() {  # stop NAME: SIGINT to its process group (what Ctrl-C does), wait; its exit code in $rc
  local pid; eval "pid=\$pid_$1"
  kill -INT -- "-$pid" 2>/dev/null; rc=0; wait "$pid" || rc=$?
}
graph() {  # graph CMD...: a ros2 CLI call about a running node, retried while the daemon's graph says the node
  local out      # is not there (seen once right after the node had answered: the graph mid-update)
  for _ in 1 2 3; do out=$("$@" 2>&1); grep -q "Node not found" <<< "$out" || break; sleep 1; done
  echo "$out"
}
param() { graph ros2 param get "$1" "$2"; }
launch_until_warm() {  # launch_until_warm NAME ARGS...: the launch file (node smoke_NAME) until the node's warm-up
  local name=$1; shift  # line, then stopped; its output in $log/NAME
  start "$name" ros2 launch flow_node flow_node.launch.py node_name:="smoke_$name" "$@"
  for _ in $(seq 60); do grep -q "engine warm-up" "$log/$name" && break; sleep 1; done
  stop "$name"
}
has() { grep -Eq -- "$2" <<< "$1"; }  # has TEXT PATTERN (no pipe: grep -q closing it early breaks pipefail)

[ -f "$share/config/fastest.yaml" ] && [ -f "$share/launch/flow_node.launch.py" ] || fail "no config/launch in $share"
ros2 run flow_node flow_bag --help > /dev/null || fail "flow_bag --help"

# a relative params file that does not exist here: one line, exit 1 (no traceback)
out=$(ros2 run flow_node flow_node --ros-args --params-file config/flow_node.yaml 2>&1)
grep -q "cannot start: cannot read parameter file config/flow_node.yaml" <<< "$out" || fail "missing params file: $out"
! grep -q Traceback <<< "$out" || fail "traceback for a missing params file: $out"
echo "ok: missing params file -> $(grep 'cannot start' <<< "$out")"

ros2 daemon start > /dev/null 2>&1; sleep 2
start node ros2 run flow_node flow_node --ros-args -r image:=/smoke/image -r __node:=smoke_flow \
  --params-file "$share/config/fastest.yaml"
# (the answer that ended the wait is the one checked)
for _ in $(seq 60); do v=$(param /smoke_flow preset); has "$v" "String value is: fastest" && break; sleep 1; done
has "$v" "String value is: fastest" || fail "node not up: $v $(cat "$log/node")"
has "$(param /smoke_flow finest_level)" "Integer value is: 1" || fail "fastest finest_level"
has "$(graph ros2 param set /smoke_flow preset quality)" "Set parameter successful" || fail "param set preset quality"
has "$(param /smoke_flow finest_level)" "Integer value is: 0" || fail "quality kept finest_level: $(param /smoke_flow finest_level)"
echo "ok: preset fastest -> quality sets finest_level 0"

# the node's first warm-up compiles its kernels (a fresh workspace has an empty numba cache: tens of seconds, while
# the parameter services answer); the bag is played after it, so the check below times the flow, not the compiler
for _ in $(seq 150); do grep -q "engine warm-up" "$log/node" && break; sleep 1; done
grep -q "engine warm-up" "$log/node" || fail "no engine warm-up line within 150 s: $(cat "$log/node")"

# flow_bag play into the node, stopped with Ctrl-C: exit 0 and the real count, no rcl remap warning
start play ros2 run flow_node flow_bag play "$bag" --loop --topic-remap /camera/image_raw:=/smoke/image
sleep 4
has "$(ros2 topic list)" "^/smoke_flow/flow$" || fail "no /smoke_flow/flow topic"
pair=$(timeout 20 ros2 topic echo --once /smoke_flow/flow_pair sensor_msgs/msg/TimeReference 2>&1)
has "$pair" "source: earlier_frame" || fail "no flow from the played bag: $pair $(cat "$log/node")"
echo "ok: the node publishes flow for the played bag (~/flow_pair received)"
stop play
grep -Eq "^flow_bag play: stopped by Ctrl-C after publishing [1-9][0-9]* messages$" "$log/play" || fail "play: $(cat "$log/play")"
! grep -qi deprecated "$log/play" || fail "play printed a deprecation warning: $(cat "$log/play")"
[ "$rc" = 0 ] || fail "play exit code $rc: $(cat "$log/play")"
echo "ok: $(cat "$log/play") (exit $rc)"
stop node
[ "$rc" = 0 ] || fail "node exit code $rc: $(cat "$log/node")"
! grep -q Traceback "$log/node" || fail "node traceback: $(cat "$log/node")"

# the launch file with its arguments
start launch ros2 launch flow_node flow_node.launch.py image:=/smoke/cam node_name:=smoke_launch \
  namespace:=/smoke params_file:="$share/config/fastest.yaml" log_level:=info
for _ in $(seq 60); do v=$(param /smoke/smoke_launch preset); has "$v" "String value is: fastest" && break; sleep 1; done
has "$v" "String value is: fastest" || fail "launch: $v $(cat "$log/launch")"
has "$(graph ros2 node info /smoke/smoke_launch)" "/smoke/cam: sensor_msgs/msg/Image" || fail "launch remap image"
stop launch
! grep -q Traceback "$log/launch" || fail "launch traceback: $(cat "$log/launch")"
! grep -qi "XMLPARSER\|error" "$log/launch" || fail "launch (Fast DDS profile) errors: $(cat "$log/launch")"
grep -q "middleware rmw_fastrtps_cpp, profile $share/config/fastdds_localhost.xml" "$log/launch" \
  || fail "launch: the node did not apply the shipped Fast DDS profile: $(cat "$log/launch")"
echo "ok: ros2 launch with image, node_name, namespace, params_file, log_level; the shipped DDS profile (exit $rc)"

# dds_profile:= gives the node's process another profile, which the node keeps
cp "$share/config/fastdds_localhost.xml" "$log/mine.xml"
launch_until_warm launch2 dds_profile:="$log/mine.xml"
grep -q "middleware rmw_fastrtps_cpp, profile $log/mine.xml" "$log/launch2" \
  || fail "launch dds_profile:= not in effect: $(cat "$log/launch2")"
echo "ok: ros2 launch dds_profile:=FILE"
# the user's transport choice wins under launch too (docs/node.md, "Middleware")
FASTDDS_BUILTIN_TRANSPORTS=UDPv4 launch_until_warm launch3
grep -q "middleware rmw_fastrtps_cpp, built-in transports UDPv4" "$log/launch3" \
  || fail "launch overrode FASTDDS_BUILTIN_TRANSPORTS: $(cat "$log/launch3")"
echo "ok: ros2 launch keeps the user's FASTDDS_BUILTIN_TRANSPORTS"

# the managed (lifecycle) node through the ros2 lifecycle CLI (docs/node.md, "Managed (lifecycle) node")
life() { graph ros2 lifecycle "$1" /smoke_life ${2:+"$2"}; }
flow_within() { timeout "$1" ros2 topic echo --once /smoke_life/flow_pair sensor_msgs/msg/TimeReference 2>&1; }
start managed ros2 run flow_node flow_node --ros-args -r __node:=smoke_life -r image:=/smoke/life \
  --params-file "$share/config/fastest.yaml" -p managed:=true
for _ in $(seq 60); do v=$(life get); has "$v" "^unconfigured \[1\]" && break; sleep 1; done
has "$v" "^unconfigured \[1\]" || fail "managed node not waiting unconfigured: $v $(cat "$log/managed")"
has "$(param /smoke_life preset)" "String value is: fastest" || fail "unconfigured: parameter service"
has "$(life set configure)" "Transitioning successful" || fail "lifecycle set configure: $(cat "$log/managed")"
has "$(life get)" "^inactive \[2\]" || fail "configure did not make it inactive: $(life get)"
grep -q "engine warm-up" "$log/managed" || fail "configure returned before the warm-up: $(cat "$log/managed")"
start play2 ros2 run flow_node flow_bag play "$bag" --loop --topic-remap /camera/image_raw:=/smoke/life
sleep 2
out=$(flow_within 6)
! has "$out" "earlier_frame" || fail "an inactive node published flow: $out"
has "$(graph ros2 param set /smoke_life iterations 7)" "Set parameter successful" || fail "inactive: param set"
has "$(param /smoke_life iterations)" "Integer value is: 7" || fail "inactive: param get"
diag=$(timeout 10 ros2 topic echo --once /diagnostics diagnostic_msgs/msg/DiagnosticArray 2>&1)
has "$diag" "value: inactive" || fail "diagnostics do not report the lifecycle state: $diag"
echo "ok: ros2 lifecycle get/set configure; inactive: no flow while frames come, parameters answer, diagnostics say so"
has "$(life set activate)" "Transitioning successful" || fail "lifecycle set activate: $(cat "$log/managed")"
has "$(life get)" "^active \[3\]" || fail "activate: $(life get)"
out=$(flow_within 20)
has "$out" "source: earlier_frame" || fail "no flow once active: $out $(cat "$log/managed")"
has "$(life set deactivate)" "Transitioning successful" || fail "lifecycle set deactivate: $(cat "$log/managed")"
has "$(life get)" "^inactive \[2\]" || fail "deactivate: $(life get)"
sleep 1
out=$(flow_within 6)
! has "$out" "earlier_frame" || fail "flow after deactivate: $out"
has "$(param /smoke_life iterations)" "Integer value is: 7" || fail "deactivate lost the parameters"
echo "ok: ros2 lifecycle set activate (flow) and deactivate (no flow, parameters kept)"
stop play2
has "$(life set shutdown)" "Transitioning successful" || fail "lifecycle set shutdown: $(cat "$log/managed")"
for _ in $(seq 20); do kill -0 "$pid_managed" 2>/dev/null || break; sleep 0.5; done
rc=0; wait "$pid_managed" || rc=$?
[ "$rc" = 0 ] || fail "managed node exit code $rc after shutdown: $(cat "$log/managed")"
! grep -q Traceback "$log/managed" || fail "managed node traceback: $(cat "$log/managed")"
echo "ok: ros2 lifecycle set shutdown: the process exits 0"

# the launch file brings a managed node to active itself, or leaves it to a manager
start launch4 ros2 launch flow_node flow_node.launch.py node_name:=smoke_lm managed:=true
for _ in $(seq 60); do v=$(graph ros2 lifecycle get /smoke_lm); has "$v" "^active \[3\]" && break; sleep 1; done
has "$v" "^active \[3\]" || fail "launch managed:=true did not activate: $v $(cat "$log/launch4")"
stop launch4
! grep -qi "traceback\|error" "$log/launch4" || fail "launch managed:=true: $(cat "$log/launch4")"
start launch5 ros2 launch flow_node flow_node.launch.py node_name:=smoke_lu managed:=true autostart:=false
for _ in $(seq 60); do v=$(graph ros2 lifecycle get /smoke_lu); has "$v" "^unconfigured" && break; sleep 1; done
sleep 2
has "$(graph ros2 lifecycle get /smoke_lu)" "^unconfigured \[1\]" || fail "autostart:=false: $(cat "$log/launch5")"
has "$(graph ros2 lifecycle set /smoke_lu configure)" "Transitioning successful" || fail "launch5 configure"
stop launch5
echo "ok: ros2 launch managed:=true (active on its own) and autostart:=false (waits for a manager)"
