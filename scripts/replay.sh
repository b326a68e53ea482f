#!/usr/bin/env bash
# Replay a recorded run over DDS: every topic of the MCAP bag with its original timing (log times)
# scaled by --rate, its recorded QoS and payload bytes, plus /clock.
#   scripts/replay.sh RUN_DIR|BAG_DIR [--rate R] [--loop] [--topics T ...] [--domain-id N]
#                     [--no-clock] [--delay S] [--wait-for-subscribers]
# Watch it with `uh topic echo /uh1/state --domain-id N` (same CYCLONEDDS_URI, see docs/report.md),
# `ros2 topic echo` on a ROS 2 machine, RViz2 or Foxglove Studio. Ctrl-C stops it.
# On a ROS 2 machine with the workspace sourced this is `ros2 run uh_runtime replay_node ...`.
set -euo pipefail
if [ -n "${ROS_DISTRO:-}" ] && command -v ros2 >/dev/null && [ "${UH_BACKEND:-}" != "dds" ]; then
  exec python3 -m uh_runtime.bags.replay "$@"
fi
source "$(dirname "${BASH_SOURCE[0]}")/_venv.sh"
exec replay_node "$@"
