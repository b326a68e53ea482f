#!/usr/bin/env bash
# Run a UH formation-containment team, one process per node, recorded to MCAP.
#   scripts/run_formation.sh [--scenario FILE|paper] [--case proposed|case1|case2]
#                            [--clock lockstep|realtime] [--rate R] [--duration S]
#                            [--out DIR] [--force] [--domain-id N]
# Output: DIR/bag/ (rosbag2 MCAP), DIR/metrics.json, DIR/logs/ (one log per node).
# Sets up .venv on first use. On a ROS 2 machine with the workspace sourced, nodes start with ros2 run.
set -euo pipefail
if [ -n "${ROS_DISTRO:-}" ] && command -v ros2 >/dev/null && [ "${UH_BACKEND:-}" != "dds" ]; then
  exec python3 -P -m uh_bringup.run_formation "$@"
fi
source "$(dirname "${BASH_SOURCE[0]}")/_venv.sh"
exec python -P -m uh_bringup.run_formation "$@"
