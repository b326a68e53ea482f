"""One fault injection the way ``ros2 topic pub --once`` (Jazzy) sends it, for the recorder tests.

    python once_publisher.py TOPIC   (ROS_DOMAIN_ID and CYCLONEDDS_URI from the environment)

A reliable, volatile writer that waits until one subscription has matched (checked every 0.1 s),
publishes one ``ActuatorFault`` at once, keeps alive 0.1 s and exits: a late-joining reader never
sees it.
"""
import sys
import time

import uh_runtime as rt
from uh_runtime import messages as m
from uh_wire import topics


def main() -> int:
    topic = sys.argv[1]
    rt.init(args=[sys.argv[0]])
    node = rt.Node('once_publisher')
    pub = node.create_publisher(m.ActuatorFault, topic,
                                topics.qos_profile(topics.QosSpec('reliable', 'volatile', 'keep_last', 7)))
    deadline = time.monotonic() + 30
    while pub.get_subscription_count() < 1:
        if time.monotonic() > deadline:
            sys.exit('once_publisher: no subscription within 30 s')
        time.sleep(0.1)
    msg = m.ActuatorFault(uh_id=1, channel=2, rho=0.5, onset_time=3.0)
    pub.publish(msg)
    time.sleep(0.1)
    print('published 1', flush=True)
    node.destroy_node()
    rt.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
