"""A misbehaving participant for the reliability tests.

It joins a running team and publishes invalid messages on its topics, with the registry's QoS (so they reach every
receiver), then exits.

    python reliability_rogue_publisher.py   (ROS_DOMAIN_ID and CYCLONEDDS_URI from the environment)

Sent, in order, each once:

- on /uh1/fault: rho 1.5; a NaN constant bias; channel 7; a fault naming uh3; rho 0 with its onset
  after the end of the run (valid: a stuck actuator, accepted with a warning, never acting);
- on /uh2/state: a state with NaN position; a finite state carrying uh_id 9;
- on /uh1/command: a command with an infinite collective; a finite command carrying uh_id 9.

Prints ``sent`` when every message has been acknowledged by every matched reader.
"""
import math
import sys
import time

import uh_runtime as rt
from uh_runtime import messages as m
from uh_wire import topics


def _wait(node, topic: str, subscribers: int, deadline: float) -> None:
    while node.count_subscribers(topic) < subscribers:
        if time.monotonic() > deadline:
            sys.exit(f'rogue: {topic} has {node.count_subscribers(topic)} subscribers, expected {subscribers}')
        rt.spin_once(node, timeout_sec=0.05)


def main() -> int:
    rt.init(args=[sys.argv[0]])
    node = rt.Node('rogue')
    step_qos = topics.qos_profile(topics.STEP_QOS)
    fault_pub = node.create_publisher(m.ActuatorFault, '/uh1/fault', topics.qos_profile(topics.FAULT.qos))
    state_pub = node.create_publisher(m.UHState, '/uh2/state', step_qos)
    command_pub = node.create_publisher(m.ActuatorCommand, '/uh1/command', step_qos)
    deadline = time.monotonic() + 30
    _wait(node, '/uh1/fault', 2, deadline)     # the simulator and the recorder
    _wait(node, '/uh2/state', 4, deadline)     # controllers of uh2, uh3, uh4 and the recorder
    _wait(node, '/uh1/command', 3, deadline)   # the simulator, the clock and the recorder
    end = time.monotonic() + 1.0               # let the matches complete on both sides
    while time.monotonic() < end:
        rt.spin_once(node, timeout_sec=0.05)

    def fault(**fields):
        msg = m.ActuatorFault()
        msg.uh_id, msg.channel, msg.rho, msg.onset_time = 1, 0, 1.0, 0.0
        for key, value in fields.items():
            setattr(msg, key, value)
        fault_pub.publish(msg)

    fault(rho=1.5)
    fault(rho=0.9, bias_constant=math.nan)
    fault(channel=7, rho=0.9)
    fault(uh_id=3, rho=0.9)
    fault(rho=0.0, onset_time=1.0e6)

    import numpy as np

    from uh_wire.wire import command_to_msg, state_to_msg
    bad_state = state_to_msg(2, 100, 1.0, np.zeros(12))
    bad_state.position.x = math.nan
    state_pub.publish(bad_state)
    state_pub.publish(state_to_msg(9, 100, 1.0, np.zeros(12)))
    command_pub.publish(command_to_msg(1, 100, 1.0, [math.inf, 0.0, 0.0, 0.0]))
    command_pub.publish(command_to_msg(9, 100, 1.0, [0.0, 0.0, 0.0, 0.0]))
    for pub in (fault_pub, state_pub, command_pub):
        pub.wait_for_all_acked(rt.Duration(seconds=10.0))
    print('sent', flush=True)
    node.destroy_node()
    rt.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
