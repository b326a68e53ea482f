#!/usr/bin/env bash
# Run a UH formation-containment team, one process per node, recorded to MCAP.
#   scripts/run_formation.sh [--scenario FILE|paper] [--case proposed|case1|case2]
#                            [--clock lockstep|realtime] [--rate R] [--duration S]
#                            [--out DIR] [--force] [--domain-id N] [--processes per-node|per-uh|single]
#                            [--respawn] [--stale-timeout S] [--hosts local|netns] [--loss PCT]
#                            [--no-metrics] [--no-report] [--secure [--keystore DIR]]   (--help: every option)
# Output: DIR/bag/ (rosbag2 MCAP), DIR/metrics.json, DIR/report/index.html (metrics, errors and XY
# snapshots), DIR/logs/ (one log per node), DIR/run.json.
# Exit status: 0 ok, 1 run failed, 2 bad input (nothing started), 3 completed with node failures,
# 130 interrupted. Failures, respawns, lossy links: docs/reliability.md.
# Sets up .venv on first use. On a ROS 2 machine with the workspace sourced, nodes start with ros2 run.
# UH_ROS_WHEELS=1: the team's nodes on real rclpy (Fast DDS) without a ROS 2 install, from .venv-rclpy
# (PyPI's unofficial ROS 2 Jazzy wheels, for testing; docs/ros2.md#rclpy-from-pypi-wheels), started
# through that virtualenv's entry points; UH_DDS_PROCESSES=uh1_controller,... puts some on Cyclone DDS.
# --secure: DDS Security, every node a process with its own identity of the keystore DIR (default: a new one
# in OUT/keystore), on .venv-secure (Cyclone DDS 0.10.2 with its plugins; set up here): docs/security.md.
set -euo pipefail
for arg in "$@"; do
  if [ "$arg" = --secure ]; then
    source "$(dirname "${BASH_SOURCE[0]}")/_venv_secure.sh"
    exec python -P -m uh_bringup.run_formation "$@"
  fi
done
if [ "${UH_ROS_WHEELS:-}" = 1 ]; then
  source "$(dirname "${BASH_SOURCE[0]}")/_venv_rclpy.sh"
  exec python -P -m uh_bringup.run_formation "$@"
fi
if [ -n "${ROS_DISTRO:-}" ] && command -v ros2 >/dev/null && [ "${UH_BACKEND:-}" != "dds" ]; then
  exec python3 -P -m uh_bringup.run_formation "$@"
fi
source "$(dirname "${BASH_SOURCE[0]}")/_venv.sh"
exec python -P -m uh_bringup.run_formation "$@"
