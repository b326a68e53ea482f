"""``uh``: inspect a running UH stack over DDS discovery, without ROS (output shaped like ``ros2``).

::

    uh topic list [-t]             ROS topics (and types) of the domain
    uh topic echo TOPIC [--once]   print messages as YAML, separated by ---
    uh topic hz TOPIC              receive rate
    uh topic info TOPIC [-v]       type, publishers, subscriptions (-v: nodes, GIDs, QoS)
    uh node list                   nodes, from ros_discovery_info
    uh param list [NODE]           parameters of a node (or of every node), like ros2 param list
    uh param get NODE NAME         a parameter's value
    uh param set NODE NAME VALUE   set a parameter (VALUE typed as YAML, like ros2 param set)
    uh param describe NODE NAME    a parameter's descriptor

Every command takes ``--domain-id`` (default ``ROS_DOMAIN_ID`` or 0). Discovery uses the Cyclone
configuration in ``CYCLONEDDS_URI``, else the runs' default
(:func:`uh_runtime.network.default_cyclonedds_uri`: loopback only, or as
``ROS_AUTOMATIC_DISCOVERY_RANGE`` and ``ROS_STATIC_PEERS`` say).

With a run's node table (``UH_RUN_NODES`` from its ``env.sh``, :mod:`uh_runtime.cli.node_table`), ``topic
list``, ``topic info``, ``node list`` and ``param list`` wait for those nodes, or name the ones not seen.
"""
import argparse
import math
import os
import sys
import time

from ..command_line import ArgumentParser
from ..dds import arguments as ros_arguments
from ..names import ROS_TOPIC_PREFIX
from ..network import MAX_DOMAIN_ID, apply_network_default
from .node_table import RUN_NODES_VARIABLE, report_missing, run_nodes

# The graph, the message classes, the QoS conversions and the DDS backend are imported inside the
# commands that use them: they load Cyclone DDS and every message type, and ``uh --help`` and a
# mistyped command must answer at once.

__all__ = ['main', 'build_parser']


#: How long the graph must stay unchanged before a listing without a run's node table is complete, s:
#: one heartbeat period (3 s) of a Fast DDS participant's ``ros_discovery_info`` writer, in case the
#: renewed reader (:data:`uh_runtime.dds.graph.INFO_GRACE`) misses its first (docs/ros2.md).
QUIET = 3.2

#: Default ``--spin-time``: the longest wait, which the quiet time must fit in.
SPIN_TIME = 4.0


class CliError(Exception):
    """A user-facing failure (nothing found in the domain, no answer): ``uh: error: ...``, exit status 1."""


class UsageError(CliError):
    """Bad input (a value out of range, an invalid name): printed as ``uh: error: ...`` with exit status 2."""


def _seconds(text: str) -> float:
    """Read a duration option: a finite number of seconds > 0."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f'{text!r}: allowed a finite number of seconds > 0')
    return value


def _count(lowest: int):
    """Return an argparse type for an integer option of at least ``lowest``."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = lowest - 1
        if value < lowest:
            raise argparse.ArgumentTypeError(f'{text!r}: allowed an integer >= {lowest}')
        return value
    return parse


def _domain_default():
    value = os.environ.get('ROS_DOMAIN_ID', '').strip()
    return int(value) if value else 0


def _common(parser, spin_time=True):
    parser.add_argument('--domain-id', type=int, default=None,
                        help='DDS domain id (default: ROS_DOMAIN_ID, else 0)')
    if spin_time:
        parser.add_argument('--spin-time', type=_seconds, default=SPIN_TIME,
                            help=f'longest time to wait for discovery, s (default: {SPIN_TIME}; the answer comes '
                                 f'as soon as every node of {RUN_NODES_VARIABLE} (a run\'s env.sh) is seen, '
                                 f'without it once nothing new was discovered for {QUIET} s)')


def build_parser():
    """Return the argument parser of ``uh``: the ``topic``, ``node`` and ``param`` commands and their verbs."""
    parser = ArgumentParser(
        prog='uh', description='Inspect ROS 2 topics and nodes of a DDS domain over Cyclone DDS '
        '(works without ROS; output like the ros2 CLI).')
    commands = parser.add_subparsers(dest='command', metavar='{topic,node,param}')
    commands.required = True

    topic = commands.add_parser('topic', help='topics: list, echo, hz, info')
    verbs = topic.add_subparsers(dest='verb', metavar='{list,echo,hz,info}')
    verbs.required = True

    p = verbs.add_parser('list', help='list the ROS topics of the domain')
    p.add_argument('-t', '--show-types', action='store_true', help='also show each topic\'s type')
    _common(p)

    p = verbs.add_parser('echo', help='print the messages of a topic as YAML')
    p.add_argument('topic_name', help='ROS topic name, e.g. /uh1/state')
    p.add_argument('message_type', nargs='?', help='type (default: from the publishers), '
                   'e.g. uh_msgs/msg/UHState')
    p.add_argument('--once', action='store_true', help='print the first message and exit')
    p.add_argument('--field', help='print only this field, e.g. position.x')
    p.add_argument('--timeout', type=_seconds, default=None,
                   help='give up (exit 1) if nothing arrives within this many seconds')
    p.add_argument('--truncate-length', type=_count(0), default=128,
                   help='longest array or string printed in full (default 128)')
    p.add_argument('--qos-depth', type=_count(1), default=10, help='history depth of the reader')
    _common(p, spin_time=False)

    p = verbs.add_parser('hz', help='print the receive rate of a topic')
    p.add_argument('topic_name')
    p.add_argument('--window', '-w', type=_count(1), default=10000, help='window size in messages')
    p.add_argument('--timeout', type=_seconds, default=None,
                   help='exit after this many seconds (status 1 if nothing arrived)')
    _common(p, spin_time=False)

    p = verbs.add_parser('info', help='type and endpoints of a topic')
    p.add_argument('topic_name')
    p.add_argument('-v', '--verbose', action='store_true',
                   help='show node, GID, type hash and QoS of every endpoint')
    _common(p)

    node = commands.add_parser('node', help='nodes: list')
    nverbs = node.add_subparsers(dest='verb', metavar='{list}')
    nverbs.required = True
    p = nverbs.add_parser('list', help='list the nodes of the domain')
    p.add_argument('-c', '--count-nodes', action='store_true', help='only print the number of nodes')
    _common(p)

    param = commands.add_parser('param', help='parameters of running nodes: list, get, set, describe')
    pverbs = param.add_subparsers(dest='verb', metavar='{list,get,set,describe}')
    pverbs.required = True
    p = pverbs.add_parser('list', help='list the parameters of a node (default: of every node)')
    p.add_argument('node_name', nargs='?', help='fully qualified node name, e.g. /uh1/controller')
    _common(p)
    for verb, text in (('get', 'print a parameter\'s value'), ('describe', 'print a parameter\'s descriptor'),
                       ('set', 'set a parameter')):
        p = pverbs.add_parser(verb, help=text)
        p.add_argument('node_name', help='fully qualified node name, e.g. /uh1/controller')
        p.add_argument('parameter_name', help='parameter name, e.g. stale_timeout')
        if verb == 'set':
            p.add_argument('value', help='new value, typed as YAML (1 int, 1.0 double, true bool, [1, 2] ...)')
        _common(p)
    return parser


def _graph(args):
    from ..dds.graph import Graph
    domain = _domain_default() if args.domain_id is None else args.domain_id
    if not 0 <= domain <= MAX_DOMAIN_ID:
        raise UsageError(f'--domain-id {domain} is outside 0..{MAX_DOMAIN_ID} (the range ROS 2 allows)')
    return Graph(domain_id=domain)


def _check_topic(name):
    if not name.startswith('/'):
        name = '/' + name
    try:
        return ros_arguments.validate_full_topic_name(name)
    except ros_arguments.InvalidNameError as exc:
        raise UsageError(str(exc)) from None


def _discover(args) -> list:
    """Collect discovery as ``--spin-time`` says (waiting for the run's nodes); return those not seen."""
    try:
        args.table = run_nodes(args.domain_id)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    return args.graph.settle(args.spin_time, quiet=min(QUIET, args.spin_time), expected=args.table)


def _complete(args, missing: list) -> int:
    return report_missing(missing, len(args.table), args.spin_time)


# ----------------------------------------------------------------------------------------------
def cmd_topic_list(args):
    graph = args.graph
    missing = _discover(args)
    for name, types in graph.topic_names_and_types():
        if args.show_types:
            print(f"{name} [{', '.join(types)}]")
        else:
            print(name)
    return _complete(args, missing)


def cmd_node_list(args):
    missing = _discover(args)
    nodes = args.graph.full_node_names()
    if args.count_nodes:
        print(len(nodes))
    elif nodes:
        print('\n'.join(nodes))
    return _complete(args, missing)


def _qos_text(profile, dds_qos):
    from cyclonedds.qos import Policy

    def dur(ns):
        return 'Infinite' if ns is None or ns >= 0x7FFFFFFFFFFFFFFF else f'{ns} nanoseconds'
    lifespan = deadline = lease = None
    liveliness = 'AUTOMATIC'
    for policy in dds_qos:
        if isinstance(policy, Policy.Lifespan):
            lifespan = policy.lifespan
        elif isinstance(policy, Policy.Deadline):
            deadline = policy.deadline
        elif isinstance(policy, Policy.Liveliness.ManualByTopic):
            liveliness, lease = 'MANUAL_BY_TOPIC', policy.lease_duration
        elif isinstance(policy, Policy.Liveliness.Automatic):
            lease = policy.lease_duration
    history = (f'KEEP_LAST ({profile.depth})' if profile.history.name == 'KEEP_LAST'
               else 'KEEP_ALL')
    return [
        'QoS profile:',
        f'  Reliability: {profile.reliability.name}',
        f'  History (Depth): {history}',
        f'  Durability: {profile.durability.name}',
        f'  Lifespan: {dur(lifespan)}',
        f'  Deadline: {dur(deadline)}',
        f'  Liveliness: {liveliness}',
        f'  Liveliness lease duration: {dur(lease)}',
    ]


def cmd_topic_info(args):
    from ..dds.graph import format_gid
    topic = _check_topic(args.topic_name)
    graph = args.graph
    missing = _discover(args)
    types = dict(graph.topic_names_and_types()).get(topic)
    if not types:
        _complete(args, missing)
        raise CliError(f"Unknown topic '{topic}'")
    pubs = graph.endpoints(topic, writers=True)
    subs = graph.endpoints(topic, writers=False)
    lines = [f"Type: {'; '.join(types)}"]
    for title, endpoints in (('Publisher count', pubs), ('Subscription count', subs)):
        if args.verbose:
            lines.append('')
        lines.append(f'{title}: {len(endpoints)}')
        if args.verbose:
            for ep in endpoints:
                lines += ['', f'Node name: {ep.node_name}', f'Node namespace: {ep.node_namespace}',
                          f'Topic type: {ep.topic_type}', f'Topic type hash: {ep.topic_type_hash}',
                          f'Endpoint type: {ep.endpoint_type}', f'GID: {format_gid(ep.gid)}']
                lines += _qos_text(ep.qos_profile, ep.dds_qos)
    print('\n'.join(lines))
    return _complete(args, missing)


def _wait_for_type(graph, topic, timeout):
    """Type of ``topic`` from its publishers (else subscribers), waiting like ``ros2 topic echo``."""
    def found(g):
        return bool(g.endpoints(topic, writers=True))

    if not graph.wait_until(found, timeout_sec=min(0.5, timeout) if timeout is not None else 0.5):
        print(f'WARNING: topic [{topic}] does not appear to be published yet; waiting for it '
              '(--timeout to give up)', file=sys.stderr, flush=True)
        remaining = None if timeout is None else max(0.0, timeout - 0.5)
        if not graph.wait_until(found, timeout_sec=remaining):
            raise CliError(f'no publisher of {topic} appeared within {timeout} s')
    pubs = graph.endpoints(topic, writers=True)
    types = sorted({ep.topic_type for ep in pubs})
    if len(types) > 1:
        raise CliError(f'{topic} is published with several types ({", ".join(types)}); '
                       'pass the type as second argument')
    return types[0], pubs


def _reader(graph, topic, cls, pubs, depth, raw=False):
    """Create a reader whose QoS suits every publisher (reliable/transient-local only if all are)."""
    from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    from .. import messages
    from ..dds.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, to_dds_qos
    reliable = pubs and all(p.qos_profile.reliability == ReliabilityPolicy.RELIABLE for p in pubs)
    latched = pubs and all(p.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in pubs)
    profile = QoSProfile(
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)
    dds_topic = Topic(graph.participant, ROS_TOPIC_PREFIX + topic, cls)
    reader = DataReader(graph.participant, dds_topic,
                        qos=to_dds_qos(profile, f'typehash={messages.type_hash(cls)};'.encode()))
    condition = ReadCondition(reader, SampleState.NotRead | ViewState.Any | InstanceState.Any)
    graph._waitset.attach(condition)
    return reader, condition


def _field(msg, path):
    value = msg
    for part in path.split('.'):
        if not hasattr(value, part):
            raise CliError(f"'{path}' is not a field of {type(msg).__name__} "
                           f"(no '{part}' in {type(value).__name__})")
        value = getattr(value, part)
    return value


def cmd_topic_echo(args):
    from .. import messages
    topic = _check_topic(args.topic_name)
    graph = args.graph
    start = time.monotonic()
    if args.message_type:
        type_name = args.message_type
        graph.update()
        pubs = graph.endpoints(topic, writers=True)
    else:
        type_name, pubs = _wait_for_type(graph, topic, args.timeout)
    try:
        cls = messages.dds_message(type_name)
    except messages.MessageError as exc:
        # a type given on the command line is bad input; one announced by the publishers is not
        raise (UsageError if args.message_type else CliError)(str(exc)) from None
    if args.field:
        try:
            _field(cls(), args.field)  # fail early on a wrong field
        except CliError as exc:
            raise UsageError(str(exc)) from None
    reader, condition = _reader(graph, topic, cls, pubs, args.qos_depth)
    while True:
        for msg in reader.take(N=256):
            if not msg.sample_info.valid_data:
                continue
            value = _field(msg, args.field) if args.field else msg
            sys.stdout.write(messages.message_to_yaml(value, truncate_length=args.truncate_length))
            sys.stdout.write('---\n')
            sys.stdout.flush()
            if args.once:
                return 0
        now = time.monotonic()
        if args.timeout is not None and now - start >= args.timeout:
            raise CliError(f'no message on {topic} within {args.timeout} s')
        remaining = None if args.timeout is None else args.timeout - (now - start)
        graph._waitset.wait(0x7FFFFFFFFFFFFFFF if remaining is None else int(remaining * 1e9))
        graph._guard.take()


def cmd_topic_hz(args):
    from .. import messages
    topic = _check_topic(args.topic_name)
    graph = args.graph
    start = time.monotonic()
    type_name, pubs = _wait_for_type(graph, topic, args.timeout)
    cls = messages.dds_message(type_name)
    reader, condition = _reader(graph, topic, cls, pubs, depth=1000)
    from cyclonedds.core import InstanceState, SampleState, ViewState

    from ..dds.binding import raw_take
    ddspy_take = raw_take()
    mask = SampleState.Any | ViewState.Any | InstanceState.Any
    stamps = []
    last_print = time.monotonic()
    last_count = 0
    received = 0
    while True:
        ret = ddspy_take(reader._ref, mask, 1000)  # raw: no deserialisation needed to count
        now = time.monotonic()
        for _, info in ret:
            if info.valid_data:
                stamps.append(now)
                received += 1
        del stamps[:-args.window - 1]
        if now - last_print >= 1.0:
            last_print = now
            if len(stamps) >= 2 and received != last_count:
                gaps = [b - a for a, b in zip(stamps, stamps[1:], strict=False)]
                mean = sum(gaps) / len(gaps)
                std = math.sqrt(sum((g - mean) ** 2 for g in gaps) / len(gaps))
                print(f'average rate: {1.0 / mean:.3f}\n\tmin: {min(gaps):.3f}s max: '
                      f'{max(gaps):.3f}s std dev: {std:.5f}s window: {len(gaps) + 1}', flush=True)
            else:
                print('no new messages', flush=True)
            last_count = received
        if args.timeout is not None and now - start >= args.timeout:
            return 0 if received else 1
        deadline = last_print + 1.0
        if args.timeout is not None:
            deadline = min(deadline, start + args.timeout)
        graph._waitset.wait(max(0, int((deadline - time.monotonic()) * 1e9)))
        graph._guard.take()


COMMANDS = {
    ('topic', 'list'): cmd_topic_list,
    ('topic', 'echo'): cmd_topic_echo,
    ('topic', 'hz'): cmd_topic_hz,
    ('topic', 'info'): cmd_topic_info,
    ('node', 'list'): cmd_node_list,
}


# ----------------------------------------------------------------------------------------------
_TYPE_NAMES = {0: 'not set', 1: 'boolean', 2: 'integer', 3: 'double', 4: 'string', 5: 'byte array',
               6: 'boolean array', 7: 'integer array', 8: 'double array', 9: 'string array'}


class _ParamClients:
    """Parameter service clients on a context of the domain (created on demand, per node and service)."""

    def __init__(self, args):
        from ..dds.context import Context
        self._context = Context()
        self._context.init(args=['uh'], domain_id=_domain_default() if args.domain_id is None else args.domain_id)
        self._clients = {}
        self._wait = args.spin_time

    def call(self, node: str, service: str, **fields):
        from ..dds.services import ServiceClient
        key = (node, service)
        if key not in self._clients:
            name = ''.join(part.capitalize() for part in service.split('_'))
            self._clients[key] = ServiceClient(self._context, f'rcl_interfaces/srv/{name}', f'{node}/{service}')
        client = self._clients[key]
        if not client.wait_for_service(self._wait):
            raise CliError(f'no parameter services of node {node!r} within {self._wait:g} s (is the node '
                           'running, in this domain? see uh node list)')
        try:
            return client.call(client.request(**fields), timeout_sec=max(self._wait, 5.0))
        except TimeoutError as exc:
            raise CliError(str(exc)) from None

    def close(self):
        self._context.try_shutdown()


def _node_name(name: str) -> str:
    """Return the fully qualified node name (``/ns/name``) of ``name``; :class:`UsageError` for an invalid one."""
    name = name if name.startswith('/') else '/' + name
    namespace, _, base = name.rpartition('/')
    try:
        ros_arguments.validate_namespace(namespace or '/')
        ros_arguments.validate_node_name(base)
    except ros_arguments.InvalidNameError as exc:
        raise UsageError(f'node {name!r}: {exc}') from None
    return name


def _value_text(msg) -> str:
    from ..dds.services import parameter_value
    value = parameter_value(msg)
    return 'Parameter not set.' if value is None else f'{_TYPE_NAMES[int(msg.type)].capitalize()} value is: {value}'


def cmd_param_list(args):
    missing = _discover(args)
    nodes = args.graph.full_node_names()
    if args.node_name:
        wanted = _node_name(args.node_name)
        if wanted not in nodes:
            _complete(args, missing)
            raise CliError(f'node {wanted!r} not found; nodes: {", ".join(sorted(nodes)) or "(none)"}')
        nodes = [wanted]
    clients = _ParamClients(args)
    try:
        for node in sorted(nodes):
            try:
                names = sorted(clients.call(node, 'list_parameters').result.names)
            except CliError as exc:
                print(f'uh: {exc}', file=sys.stderr)
                continue
            if not args.node_name:
                print(f'{node}:')
            for name in names:
                print(f'  {name}')
    finally:
        clients.close()
    return _complete(args, missing)


def cmd_param_get(args):
    clients = _ParamClients(args)
    try:
        values = clients.call(_node_name(args.node_name), 'get_parameters', names=[args.parameter_name]).values
        if not values:
            raise CliError(f'parameter {args.parameter_name!r} is not declared by {_node_name(args.node_name)}')
        print(_value_text(values[0]))
    finally:
        clients.close()
    return 0


def cmd_param_set(args):
    from ..dds.services import value_message
    from ..messages import dds_message
    value = ros_arguments.parse_parameter_value(args.value)
    clients = _ParamClients(args)
    try:
        param = dds_message('rcl_interfaces/msg/Parameter')(name=args.parameter_name, value=value_message(value))
        result = clients.call(_node_name(args.node_name), 'set_parameters', parameters=[param]).results[0]
    except TypeError as exc:
        raise UsageError(f'value {args.value!r}: {exc}') from None
    finally:
        clients.close()
    if result.successful:
        print('Set parameter successful')
        return 0
    print(f'Setting parameter failed: {result.reason}', file=sys.stderr)
    return 1


def cmd_param_describe(args):
    clients = _ParamClients(args)
    try:
        found = clients.call(_node_name(args.node_name), 'describe_parameters', names=[args.parameter_name]).descriptors
    finally:
        clients.close()
    if not found:
        raise CliError(f'parameter {args.parameter_name!r} is not declared by {_node_name(args.node_name)}')
    d = found[0]
    print(f'Parameter name: {d.name}')
    print(f'  Type: {_TYPE_NAMES.get(int(d.type), d.type)}')
    if d.description:
        print(f'  Description: {d.description}')
    print('  Constraints:')
    if d.read_only:
        print('    Read only: true')
    if d.dynamic_typing:
        print('    Dynamic typing: true')
    for r in d.floating_point_range:
        print(f'    Min value: {r.from_value}\n    Max value: {r.to_value}'
              + (f'\n    Step: {r.step}' if r.step else ''))
    for r in d.integer_range:
        print(f'    Min value: {r.from_value}\n    Max value: {r.to_value}'
              + (f'\n    Step: {r.step}' if r.step else ''))
    if d.additional_constraints:
        print(f'    {d.additional_constraints}')
    return 0


COMMANDS.update({('param', 'list'): cmd_param_list, ('param', 'get'): cmd_param_get,
                 ('param', 'set'): cmd_param_set, ('param', 'describe'): cmd_param_describe})


def main(argv=None) -> int:
    """Console script ``uh``; returns the exit status.

    0 done; 1 what was asked for is not there (no such topic, no publisher, no node answering in
    time, a node of the run's table not seen by a listing); 2 bad input (an option's value, an invalid
    name, an unknown type or field); 130 interrupted.
    """
    args = build_parser().parse_args(argv)
    # uh reads the graph through Cyclone DDS (uh_runtime.dds.graph): its message classes and QoS must be that
    # backend's also where rclpy is importable (a sourced ROS 2, .venv-rclpy), or it silently finds nothing.
    # Set for the command only: a caller in the same process keeps its own choice.
    previous = os.environ.get('UH_BACKEND')
    os.environ['UH_BACKEND'] = 'dds'
    try:
        return _run(args)
    finally:
        if previous is None:
            os.environ.pop('UH_BACKEND', None)
        else:
            os.environ['UH_BACKEND'] = previous


def _run(args) -> int:
    try:
        apply_network_default()     # the runs' network default, unless CYCLONEDDS_URI says otherwise
    except ValueError as exc:       # a bad ROS_AUTOMATIC_DISCOVERY_RANGE
        print(f'uh: error: {exc}', file=sys.stderr)
        return 2
    try:
        with _graph(args) as graph:
            args.graph = graph
            return COMMANDS[(args.command, args.verb)](args)
    except KeyboardInterrupt:
        return 130
    except CliError as exc:
        print(f'uh: error: {exc}', file=sys.stderr)
        return 2 if isinstance(exc, UsageError) else 1
    except BrokenPipeError:
        return 0

if __name__ == '__main__':
    sys.exit(main())
