"""``uh-inject-fault`` (behind ``scripts/inject_fault.sh``): inject an actuator fault at run time.

Publishes one ``uh_msgs/ActuatorFault`` on ``/uh<N>/fault`` (paper eq. 6:
u_actual = rho u + bias + amplitude sin(frequency t), from ``--onset`` on) once the UH's simulator
is listening, and exits. Values are checked here (the simulator's own fault model decides what is
valid: rho in [0, 1], finite numbers, onset >= 0) and again by the simulator, which rejects invalid
injections with a logged reason and keeps running. rho = 0 (a stuck actuator) is sent with a
warning: the controller cannot compensate it.

With ``--secure`` (a secure team, docs/security.md) it takes the operator's identity ``/tools/operator`` of
the team's keystore (``--keystore DIR``, default ``ROS_SECURITY_KEYSTORE``, which a secure run's ``env.sh``
sets), the only identity besides the simulators' readers that may touch ``/uhN/fault``.

Exit status: 0 sent and acknowledged by the simulator; 1 the team is not running in that DDS domain
(without ``--timeout``: no node at all discovered there within :data:`NO_TEAM_S`), or the simulator
did not acknowledge the fault within :data:`ACK_TIMEOUT_S`; 2 bad input (an option's value, or a UH
the running team does not have).
"""
from __future__ import annotations

import argparse
import gc
import math
import os
import re
import sys
import time

import uh_runtime as rt
from uh_bringup.run_secure import OPERATOR_ENCLAVE, SECURE_MAX_DOMAIN_ID
from uh_core.layout import CHANNEL_ALIASES, CHANNEL_NAMES
from uh_runtime import messages as m
from uh_runtime.command_line import ArgumentParser
from uh_runtime.dds.security import SecurityConfigError
from uh_runtime.network import MAX_DOMAIN_ID, apply_network_default
from uh_sim_node.faults import ActuatorFault, FaultError
from uh_wire import topics

__all__ = ['main']


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``uh-inject-fault`` / ``scripts/inject_fault.sh``."""
    p = ArgumentParser(prog='inject_fault.sh', description=__doc__.split('\n\n')[0])
    p.add_argument('--uh', type=int, required=True, help='helicopter index N (topic /uhN/fault)')
    p.add_argument('--channel', required=True, choices=sorted(CHANNEL_NAMES), help='actuator channel')
    p.add_argument('--rho', type=float, default=1.0, help='loss-of-effectiveness factor in [0, 1] (0 = stuck)')
    p.add_argument('--bias', type=float, default=0.0, help='constant bias, rad')
    p.add_argument('--amplitude', type=float, default=0.0, help='sinusoidal bias amplitude, rad')
    p.add_argument('--frequency', type=float, default=0.0, help='sinusoidal bias frequency, rad/s')
    p.add_argument('--onset', type=float, default=0.0, help='simulation time from which the fault acts, s')
    p.add_argument('--stuck', action='store_true',
                   help='stick the actuator where it is when the simulator takes this (rho = 0, its position then '
                        'as the bias); --rho and the bias and onset options are not used')
    p.add_argument('--domain-id', type=int, default=None, help='DDS domain id of the running team')
    p.add_argument('--secure', action='store_true',
                   help=f'a secure team: inject with the operator identity {OPERATOR_ENCLAVE} of --keystore')
    p.add_argument('--keystore', default=None, metavar='DIR',
                   help='with --secure: the team\'s keystore (default: ROS_SECURITY_KEYSTORE, set by a secure '
                        'run\'s env.sh)')
    p.add_argument('--timeout', type=float, default=None, metavar='S',
                   help='wait up to S s for the UH\'s simulator, e.g. of a team that is still starting '
                        f'(default: {DEFAULT_TIMEOUT_S:g} s once the team is seen; without a node in the domain '
                        f'after {NO_TEAM_S:g} s there is no team)')
    return p


#: s after the first team topic is seen before a UH without a subscriber counts as not in the team
SETTLE_S = 1.5
#: Without --timeout: s of discovery after which a domain without any node holds no team. The first
#: node of a running team is seen 0.07-0.5 s after this process's participant is created (median 0.25 s),
#: but once in 50 tries 1.4 s (one host, 2 cores at load 8-13: a real-time team and other runs); the
#: margin is for such a loaded machine.
NO_TEAM_S = 2.0
#: Without --timeout: longest wait, s, for the UH's simulator once some node is seen in the domain.
DEFAULT_TIMEOUT_S = 10.0
#: With --secure: s more before a domain without any node holds no team (a secure participant's
#: authentication handshake takes 1.5-2 s before anything of the team is seen, docs/security.md).
SECURE_HANDSHAKE_S = 3.0
#: s between two looks at the discovered graph.
POLL_S = 0.02
#: Longest wait for this writer to match the readers the graph shows on the fault topic, s.
MATCH_TIMEOUT_S = 5.0
#: Longest wait for the simulator to acknowledge the fault (a reliable topic), s.
ACK_TIMEOUT_S = 10.0     # s: a loaded machine's simulator may take seconds to read (it was 2 s, which lost one)


def _sim_listens(node, topic: str) -> bool:
    """Return whether the UH's simulator (node ``sim`` in the topic's namespace) subscribes to ``topic``.

    A recorder, which subscribes to every topic it discovers, does not count.
    """
    namespace = topic.rsplit('/', 1)[0]
    return any(info.node_name == 'sim' and info.node_namespace == namespace
               for info in node.get_subscriptions_info_by_topic(topic))


def _wait_until_matched(node, pub, topic: str) -> None:
    """Wait (at most :data:`MATCH_TIMEOUT_S`) until ``pub`` has matched every reader the graph shows on ``topic``.

    The graph shows the simulator's reader as soon as discovery announces it; this writer matches it
    a moment later, and a sample written before that would never reach it (the topic is volatile).
    """
    deadline = time.monotonic() + MATCH_TIMEOUT_S
    while pub.get_subscription_count() < len(node.get_subscriptions_info_by_topic(topic)):
        if time.monotonic() > deadline:
            return
        time.sleep(POLL_S)


def _team_uhs(node) -> list:
    """UH ids whose simulators listen for faults in the running team (from discovery)."""
    ids = set()
    for name, _types in node.get_topic_names_and_types():
        match = re.fullmatch(r'/uh(\d+)/(fault|state)', name)
        if match and (match.group(2) == 'state' or _sim_listens(node, name)):
            ids.add(int(match.group(1)))
    return sorted(ids)


def _checked_fault(parser, args) -> ActuatorFault:
    """Check the options (exit 2 naming the one at fault and what is allowed); return the fault to send."""
    for name in ('rho', 'bias', 'amplitude', 'frequency', 'onset', 'timeout'):
        value = getattr(args, name)
        if value is not None and not math.isfinite(value):
            parser.exit(2, f'{parser.prog}: error: --{name} {value}: must be a finite number\n')
    if not 0.0 <= args.rho <= 1.0:
        parser.exit(2, f'{parser.prog}: error: --rho {args.rho}: allowed 0 .. 1 (1 = healthy, 0 = stuck)\n')
    if args.uh < 1:
        parser.exit(2, f'{parser.prog}: error: --uh {args.uh}: helicopter indices start at 1\n')
    if args.domain_id is not None and not 0 <= args.domain_id <= MAX_DOMAIN_ID:
        parser.exit(2, f'{parser.prog}: error: --domain-id {args.domain_id}: allowed 0..{MAX_DOMAIN_ID}\n')
    if args.timeout is not None and not 0 < args.timeout <= 3600:
        parser.exit(2, f'{parser.prog}: error: --timeout {args.timeout}: allowed > 0 .. 3600 s\n')
    try:
        fault = ActuatorFault(channel=CHANNEL_ALIASES[args.channel], rho=args.rho, bias_constant=args.bias,
                              bias_amplitude=args.amplitude, bias_frequency=args.frequency, onset_time=args.onset)
    except FaultError as exc:
        parser.exit(2, f'{parser.prog}: error: {exc}\n')
    if args.stuck:
        print(f'{parser.prog}: warning: --stuck: the {args.channel} actuator stays where it is, which is outside '
              'what the law compensates (with resilience its controller finds it and leaves the team)', file=sys.stderr)
    elif fault.is_stuck:
        print(f'{parser.prog}: warning: --rho 0 makes the {args.channel} actuator stuck at its bias, which is '
              'outside what the controller can compensate', file=sys.stderr)
    _secure_identity(parser, args)
    return fault


def _secure_identity(parser, args) -> None:
    """With ``--secure``: check the keystore and take the operator identity (ROS 2's security variables)."""
    if not args.secure:
        if args.keystore is not None:
            parser.exit(2, f'{parser.prog}: error: --keystore {args.keystore} needs --secure\n')
        return
    args.keystore = args.keystore or os.environ.get('ROS_SECURITY_KEYSTORE')
    if not args.keystore:
        parser.exit(2, f'{parser.prog}: error: --secure needs --keystore DIR (the team\'s keystore; a secure run '
                       'prints it and its env.sh sets ROS_SECURITY_KEYSTORE)\n')
    identity = os.path.join(args.keystore, 'enclaves', OPERATOR_ENCLAVE.strip('/'), 'cert.pem')
    if not os.path.isfile(identity):
        parser.exit(2, f'{parser.prog}: error: --keystore {args.keystore}: no operator identity ({identity}); give '
                       'the keystore of the running team (uh-security create makes one)\n')
    domain = args.domain_id if args.domain_id is not None else int(os.environ.get('ROS_DOMAIN_ID') or 0)
    if domain > SECURE_MAX_DOMAIN_ID:
        parser.exit(2, f'{parser.prog}: error: --secure on DDS domain {domain}: allowed 0..{SECURE_MAX_DOMAIN_ID}\n')
    os.environ.update(ROS_SECURITY_ENABLE='true', ROS_SECURITY_STRATEGY='Enforce',
                      ROS_SECURITY_KEYSTORE=os.path.abspath(args.keystore),
                      ROS_SECURITY_ENCLAVE_OVERRIDE=OPERATOR_ENCLAVE)


def _others_in_domain(node) -> bool:
    """Whether discovery has found any node in the domain besides this one."""
    own = (node.get_name(), node.get_namespace())
    return any(entry != own for entry in node.get_node_names_and_namespaces())


def _wait_for_simulator(node, topic: str, args, prog: str) -> int | None:
    """Spin until the UH's simulator subscribes to ``topic``; return None then, else the exit status (said why).

    Without ``--timeout``: a domain where no node at all is discovered within :data:`NO_TEAM_S`
    holds no team (exit 1 then); once some node is seen, wait up to :data:`DEFAULT_TIMEOUT_S`.
    """
    start = time.monotonic()
    deadline = start + (DEFAULT_TIMEOUT_S if args.timeout is None else args.timeout)
    domain = os.environ.get('ROS_DOMAIN_ID', '0')
    team_seen = None
    someone_seen = args.timeout is not None     # an explicit --timeout waits for a team still starting
    fix = (f'is the team running in that domain? `uh node list --domain-id {domain}` lists the nodes there; '
           'a run prints its domain at start and writes it to <out>/env.sh, so pass it with --domain-id N '
           '(or source that file)')
    while not _sim_listens(node, topic):
        now = time.monotonic()
        team = _team_uhs(node)
        if team and team_seen is None:
            team_seen = now
        if team and args.uh not in team and now - team_seen > SETTLE_S:
            print(f'{prog}: error: --uh {args.uh}: the team running in DDS domain {domain} has no '
                  f'UH {args.uh}; its UHs: {", ".join(map(str, team))}', file=sys.stderr)
            return 2
        someone_seen = someone_seen or _others_in_domain(node)
        if not someone_seen and now - start > NO_TEAM_S + (SECURE_HANDSHAKE_S if args.secure else 0.0):
            print(f'{prog}: error: nobody subscribes to {topic} in DDS domain {domain}: no node at all was '
                  f'discovered there within {NO_TEAM_S:g} s; {fix}; --timeout S waits for a team that is '
                  'still starting', file=sys.stderr)
            return 1
        if now > deadline:
            print(f'{prog}: error: nobody subscribes to {topic} in DDS domain {domain} within '
                  f'{deadline - start:g} s: {fix}', file=sys.stderr)
            return 1
        # discovery runs in the DDS stack's threads: nothing to spin, so wait without using the CPU
        # (spin_once returns at once with no callbacks to run, which made this loop busy)
        time.sleep(POLL_S)
    return None


def main(argv=None) -> int:
    """Console script ``uh-inject-fault``: publish one fault once the UH's simulator listens; return the exit status.

    See the module docstring for the statuses; the simulator's acknowledgement is awaited at most
    :data:`ACK_TIMEOUT_S` s (status 1 if it does not come: the fault may not have arrived).
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    _checked_fault(parser, args)
    if args.domain_id is not None:
        os.environ['ROS_DOMAIN_ID'] = str(args.domain_id)
    try:
        apply_network_default()    # the runs' network default (uh_runtime.network.default_cyclonedds_uri)
    except ValueError as exc:      # a bad ROS_AUTOMATIC_DISCOVERY_RANGE
        parser.error(str(exc))

    rt.init(args=[sys.argv[0]])
    try:
        # a one-shot publisher: no /rosout and no parameter services, which would only slow its start
        node = rt.Node('inject_fault', enable_rosout=False, start_parameter_services=False)
    except SecurityConfigError as exc:    # --secure where Cyclone DDS has no security, or a refused identity
        rt.try_shutdown()
        parser.exit(2, f'{parser.prog}: error: security: {exc}\n')
    try:
        topic = topics.uh_topic(args.uh, topics.FAULT)
        try:
            pub = node.create_publisher(m.ActuatorFault, topic, topics.qos_profile(topics.FAULT.qos))
        except Exception as exc:    # the backend's own error type; DDS Security's refusal is said in its text
            if 'NOT_ALLOWED_BY_SECURITY' not in str(exc):
                raise
            print(f'{parser.prog}: error: this identity ({os.environ.get("ROS_SECURITY_ENCLAVE_OVERRIDE", "/")}) may '
                  f'not publish {topic} (DDS_RETCODE_NOT_ALLOWED_BY_SECURITY): a secure team takes faults from the '
                  'operator only; use --secure --keystore DIR', file=sys.stderr)
            return 2
        # as the nodes do after their start-up (uh_runtime.runner): what the imports, the message classes
        # and DDS made lives until the exit, where the interpreter's last collections walked it (0.05-0.1 s)
        gc.freeze()
        status = _wait_for_simulator(node, topic, args, parser.prog)
        if status is not None:
            return status
        _wait_until_matched(node, pub, topic)
        msg = m.ActuatorFault()
        msg.uh_id, msg.channel, msg.rho = args.uh, CHANNEL_ALIASES[args.channel], args.rho
        msg.bias_constant, msg.bias_amplitude = args.bias, args.amplitude
        msg.bias_frequency, msg.onset_time = args.frequency, args.onset
        msg.stuck_in_place = bool(args.stuck)
        if args.stuck:      # what the recording says: stuck (rho 0) on arrival; the position is the simulator's
            msg.rho, msg.bias_constant, msg.bias_amplitude, msg.onset_time = 0.0, 0.0, 0.0, 0.0
        pub.publish(msg)
        # the simulator's reliable reader acknowledges the sample before the participant goes away
        if not pub.wait_for_all_acked(rt.Duration(seconds=ACK_TIMEOUT_S)):
            print(f'{parser.prog}: error: the simulator did not acknowledge the fault within {ACK_TIMEOUT_S:g} s; it '
                  f'may not have arrived (its log and {topics.uh_topic(args.uh, topics.FAULT_TRUTH)} say)',
                  file=sys.stderr)
            return 1
        what = ('stuck where it is' if args.stuck else
                f'rho {args.rho}, bias {args.bias} + {args.amplitude} sin({args.frequency} t), from t = {args.onset} s')
        print(f'injected on {topic}: {args.channel} {what}', file=sys.stderr)
        return 0
    finally:
        # shutdown first: the DDS backend's then destroys the node without announcing it in
        # ros_discovery_info; peers see it go with the participant, whose deletion would otherwise
        # wait for every reader in the team to acknowledge that announcement (0.15-0.2 s)
        rt.try_shutdown()
        node.destroy_node()


if __name__ == '__main__':
    sys.exit(main())
