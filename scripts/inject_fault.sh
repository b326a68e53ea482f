#!/usr/bin/env bash
# Inject an actuator fault into a running team (publishes uh_msgs/ActuatorFault on /uhN/fault).
#   scripts/inject_fault.sh --uh 4 --channel collective --rho 0.7 [--bias 0.01] [--amplitude A]
#                           [--frequency W] [--onset T] [--domain-id N]
# On a ROS 2 machine the same can be done with:
#   ros2 topic pub --once /uh4/fault uh_msgs/msg/ActuatorFault "{uh_id: 4, channel: 0, rho: 0.7, onset_time: 30.0}"
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/_venv.sh"
exec uh-inject-fault "$@"
