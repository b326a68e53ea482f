#!/usr/bin/env bash
# Inject an actuator fault into a running team (publishes uh_msgs/ActuatorFault on /uhN/fault).
#   scripts/inject_fault.sh --uh 4 --channel collective --rho 0.7 [--bias 0.01] [--amplitude A]
#                           [--frequency W] [--onset T] [--domain-id N] [--timeout S] [--secure [--keystore DIR]]
# Exit status: 0 sent, 1 no team in that DDS domain, 2 bad input (a value outside what the fault
# model allows, or a UH the running team does not have). rho 0 (stuck) is sent with a warning.
# A domain where no node is discovered within 2 s holds no team (exit 1, said 2.3-3 s after the start);
# --timeout S waits up to S s for a team that is still starting. With a team running it answers once the
# simulator has acknowledged the fault: 0.6-0.7 s beside a realtime paper team on 2 cores (0.3 s of CPU;
# up to 1 s and more when other work loads the machine).
# On a ROS 2 machine the same can be done with:
#   ros2 topic pub --once /uh4/fault uh_msgs/msg/ActuatorFault "{uh_id: 4, channel: 0, rho: 0.7, onset_time: 30.0}"
# --secure: a secure team's (docs/security.md), with the operator identity /tools/operator of its keystore
# (--keystore DIR, default ROS_SECURITY_KEYSTORE from the run's env.sh), on .venv-secure. Without --secure in a
# shell that set ROS_SECURITY_ENABLE=true (a secure run's env.sh) it runs on .venv-secure with that shell's identity.
set -euo pipefail
case " $* " in
  *" --secure "*) source "$(dirname "${BASH_SOURCE[0]}")/_venv_secure.sh" ;;
  *) if [ "${ROS_SECURITY_ENABLE:-}" = true ]; then
       source "$(dirname "${BASH_SOURCE[0]}")/_venv_secure.sh"
     else
       source "$(dirname "${BASH_SOURCE[0]}")/_venv.sh"
     fi ;;
esac
exec uh-inject-fault "$@"
