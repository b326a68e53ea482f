"""Publisher for the recorder-integrity tests: N UHState messages on /uh1/state, steps 0..N-1.

    python reliability_talker.py N   (ROS_DOMAIN_ID and CYCLONEDDS_URI from the environment)

Waits until a subscriber (the recorder) has matched, publishes the N messages at once (reliable,
transient-local like the per-step topics, with a history of N so that the writer never drops a
sample a slower reader has not acknowledged yet), waits until every matched reader acknowledged
them, prints ``published N`` and exits.
"""
import sys
import time

import numpy as np

import uh_runtime as rt
from uh_runtime import messages as m
from uh_wire import topics
from uh_wire.wire import state_to_msg


def main() -> int:
    count = int(sys.argv[1])
    rt.init(args=[sys.argv[0]])
    node = rt.Node('talker')
    qos = topics.qos_profile(topics.QosSpec('reliable', 'transient_local', 'keep_last', count))
    pub = node.create_publisher(m.UHState, '/uh1/state', qos)
    deadline = time.monotonic() + 30
    while pub.get_subscription_count() == 0:
        if time.monotonic() > deadline:
            sys.exit('talker: no subscriber within 30 s')
        rt.spin_once(node, timeout_sec=0.05)
    x = np.zeros(12)
    for k in range(count):
        x[0] = k
        pub.publish(state_to_msg(1, k, k * 0.01, x))
    ok = pub.wait_for_all_acked(rt.Duration(seconds=30.0))
    print(f'published {count}' if ok else 'not acknowledged', flush=True)
    node.destroy_node()
    rt.try_shutdown()
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
