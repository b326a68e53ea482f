"""Test process of the secure tier: one DDS participant with (or without) an identity, one endpoint, stdout lines.

``secure_peer.py publish TOPIC TYPE SECONDS``, ``subscribe TOPIC TYPE SECONDS``, ``look TOPIC SECONDS`` or
``cli_node SECONDS`` (the topics of a ``ros2`` command's own node: :func:`cli_node`).
The identity comes from the environment, as for any node (ROS_SECURITY_ENABLE, ROS_SECURITY_KEYSTORE,
ROS_SECURITY_ENCLAVE_OVERRIDE; uh_runtime.dds.security): the node is named after its enclave
(``/uh3/controller`` -> node ``controller`` in ``/uh3``) so that its parameter services are its own.
A publisher's steps count from ``UH_PEER_FIRST_STEP`` (0), so a reader tells two writers apart.
Lines: ``node`` once the node is up (``refused participant: ...`` when its participant is refused);
``ready`` once its endpoint exists, or ``refused <DDS error>`` when creating the topic or the endpoint
is refused; ``got <uh_id> <step>`` per message (subscribe);
``topic <DDS name>`` per DDS topic that a discovered writer publishes and ``data <n>`` for the samples of
TOPIC taken by a plain DDS reader (look, which makes no node: a bare participant). Exits after SECONDS.
"""
import os
import sys
import time

import uh_runtime as rt
from uh_runtime import messages as m
from uh_runtime.names import REPLY_PREFIX, REQUEST_PREFIX

QOS = rt.QoSProfile(depth=100, reliability=rt.ReliabilityPolicy.RELIABLE,
                    durability=rt.DurabilityPolicy.TRANSIENT_LOCAL)


def _node():
    enclave = os.environ.get('ROS_SECURITY_ENCLAVE_OVERRIDE', '/tests/peer')
    namespace, _, name = enclave.rpartition('/')
    tool = enclave.startswith('/tools/')
    try:
        node = rt.Node(name, namespace=namespace or '/', start_parameter_services=not tool)
    except Exception as exc:   # uh_runtime.dds.security.SecurityConfigError: the participant was refused
        print(f'refused participant: {exc}', flush=True)
        raise SystemExit(0) from None
    print('node', flush=True)
    return node


def _endpoint(make):
    try:
        endpoint = make()
    except Exception as exc:   # cyclonedds.core.DDSException: the topic, writer or reader was refused
        print(f'refused {exc}', flush=True)
        return None
    print('ready', flush=True)
    return endpoint


def publish(topic: str, type_name: str, seconds: float) -> None:
    node = _node()
    cls = m.get_message(type_name)
    pub = _endpoint(lambda: node.create_publisher(cls, topic, QOS))
    deadline, step = time.monotonic() + seconds, int(os.environ.get('UH_PEER_FIRST_STEP', '0'))
    while pub is not None and time.monotonic() < deadline:
        msg = cls()
        msg.uh_id, msg.step = 1 if '/uh1/' in topic else 2 if '/uh2/' in topic else 0, step
        pub.publish(msg)
        step += 1
        rt.spin_once(node, timeout_sec=0.0)
        time.sleep(0.05)


def subscribe(topic: str, type_name: str, seconds: float) -> None:
    node = _node()
    cls = m.get_message(type_name)
    _endpoint(lambda: node.create_subscription(
        cls, topic, lambda msg: print(f'got {msg.uh_id} {msg.step}', flush=True), QOS))
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        rt.spin_once(node, timeout_sec=0.05)


def look(topic: str, seconds: float) -> None:
    """Print, as a bare participant, the DDS topics its discovery shows and the samples a reader of TOPIC gets."""
    from cyclonedds.core import InstanceState, SampleState, ViewState
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    from uh_runtime.dds.binding import raw_take
    from uh_runtime.dds.graph import Graph
    from uh_runtime.dds.qos import to_dds_qos
    graph = Graph()
    cls = m.dds_message('uh_msgs/msg/UHState')
    reader = DataReader(graph.participant, Topic(graph.participant, 'rt' + topic, cls), qos=to_dds_qos(QOS, b''))
    print('ready', flush=True)
    take, mask = raw_take(), SampleState.Any | ViewState.Any | InstanceState.Any
    seen, count, deadline = set(), 0, time.monotonic() + seconds
    while time.monotonic() < deadline:
        graph.wait_until(lambda g: False, 0.1)
        for endpoint in list(graph.writers.values()):
            if endpoint.topic_name not in seen:
                seen.add(endpoint.topic_name)
                print(f'topic {endpoint.topic_name}', flush=True)
        count += sum(1 for _data, info in take(reader._ref, mask, 256) if info.valid_data)
    print(f'data {count}', flush=True)


def cli_node(seconds: float) -> None:
    """Make the DDS topics of a Jazzy ``ros2`` command's own node ``/_ros2cli_4242``, as rmw_cyclonedds does.

    Its parameter services (the runtime's node) and ``~/get_type_description``'s request reader and reply
    writer (rclpy starts that service for every node; the runtime does not, so they are made here).
    """
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    node = _endpoint(lambda: rt.Node('_ros2cli_4242'))
    if node is None:
        return
    participant, cls = node._context.participant, m.dds_message('uh_msgs/msg/UHState')   # any type: names decide
    service = '/_ros2cli_4242/get_type_description'
    _endpoint(lambda: (DataReader(participant, Topic(participant, f'{REQUEST_PREFIX}{service}Request', cls)),
                       DataWriter(participant, Topic(participant, f'{REPLY_PREFIX}{service}Reply', cls))))
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        rt.spin_once(node, timeout_sec=0.05)


def main(argv) -> int:
    role, rest = argv[1], argv[2:]
    if role == 'look':
        look(rest[0], float(rest[1]))
        return 0
    rt.init(args=[argv[0]])
    try:
        if role == 'cli_node':
            cli_node(float(rest[0]))
        else:
            (publish if role == 'publish' else subscribe)(rest[0], rest[1], float(rest[2]))
    finally:
        rt.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv))
