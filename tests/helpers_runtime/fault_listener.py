"""Test node ``sim``: subscribes to ``uh_msgs/ActuatorFault`` on ``fault`` as a UH's simulator does.

Prints one JSON line per fault on stdout and keeps spinning (its reader keeps acknowledging).
Run it in the namespace of a UH (``--ros-args -r __ns:=/uh2``) for ``inject_fault.sh`` to find it.
"""
import json
import sys

import uh_runtime as rt
from uh_runtime.messages import ActuatorFault
from uh_wire import topics


class FaultListener(rt.Node):
    def __init__(self):
        super().__init__('sim')
        self.sub = self.create_subscription(ActuatorFault, topics.FAULT.name, self.on_fault,
                                            topics.qos_profile(topics.FAULT.qos))

    def on_fault(self, msg):
        print(json.dumps({'uh_id': msg.uh_id, 'channel': msg.channel, 'rho': msg.rho,
                          'onset_time': msg.onset_time}), flush=True)


def main(args=None):
    return rt.run_node(FaultListener, args)


if __name__ == '__main__':
    sys.exit(main(sys.argv))
