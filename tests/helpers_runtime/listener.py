"""Test node: subscribes to UHState on ``state`` and prints one JSON line per message on stdout.

The first line is ``{"ready": true}`` once its subscription matched a publisher.
"""
import json
import sys

import uh_runtime as rt
from uh_runtime.messages import UHState

#: QoS of the subscription; the tests check that discovery reports exactly this.
STATE_QOS = rt.QoSProfile(depth=5, reliability=rt.ReliabilityPolicy.RELIABLE)


class Listener(rt.Node):
    def __init__(self):
        super().__init__('listener')
        self.declare_parameter('count', 3, rt.ParameterDescriptor(
            description='messages to print before exiting',
            integer_range=[rt.IntegerRange(from_value=1, to_value=1000)]))
        self.left = self.get_parameter('count').value
        self.sub = self.create_subscription(UHState, 'state', self.on_state, STATE_QOS)

    def on_state(self, msg):
        print(json.dumps({'uh_id': msg.uh_id, 'step': msg.step, 'x': msg.position.x,
                          'vz': msg.velocity.z, 'yaw': msg.euler.z,
                          'frame_id': msg.header.frame_id}), flush=True)
        self.left -= 1
        if self.left <= 0:
            raise SystemExit(0)


def main(args=None):
    return rt.run_node(Listener, args)


if __name__ == '__main__':
    sys.exit(main(sys.argv))
