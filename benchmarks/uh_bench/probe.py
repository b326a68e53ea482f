"""Latency probe of a real-time run: ``python -m uh_bench.probe --domain-id D --ids 1..N --out F``.

A DDS participant of its own reads ``/uhN/state`` and ``/uhN/command`` of every UH (reliable,
transient-local, deep history: nothing is lost) and keeps, per sample, the step (the message's
header stamp / dt) and the **source timestamp** DDS carries with it: the writer's wall clock when
the sample was written. Since every process of a run is on this machine, one clock, the
difference of two source timestamps is exact and does not depend on when the probe reads:

- state-to-command latency of controller i at step k:
  ``src(command_i k) - src(state_i k)`` (the sim wrote state k, the controller wrote command k);
- a **late** step: ``src(command_i k) > src(state_i k+1)``: the sim had already integrated
  step k -> k+1 (with an older command) before the command of step k was written;
- a **missed** step: no command for a step k for which the sim published state k.

On SIGINT/SIGTERM (or once it has seen the command of step ``--last-step`` of every UH) it
writes ``--out`` (JSON, one summary per controller) and exits.
"""
from __future__ import annotations

import argparse
import json
import signal
import struct
import sys

__all__ = ['main', 'summarise']

_STAMP = struct.Struct('<iI')


def _percentile(sorted_values, q: float):
    if not sorted_values:
        return None
    idx = min(len(sorted_values) - 1, max(0, int(round(q * (len(sorted_values) - 1)))))
    return sorted_values[idx]


def summarise(states: dict, commands: dict, last_step: int | None = None) -> dict:
    """Return the per-controller summary of one UH's states and commands.

    ``states`` and ``commands`` are ``{step: source_timestamp_ns}`` maps; the summary gives latency percentiles
    (us), late and missed steps (see the module docstring).
    """
    lat = []
    late = []
    for k, t_cmd in sorted(commands.items()):
        t_state = states.get(k)
        if t_state is not None:
            lat.append((t_cmd - t_state) / 1000.0)
        t_next = states.get(k + 1)
        if t_next is not None and t_cmd > t_next:
            late.append(k)
    missed = sorted(k for k in states if (last_step is None or k <= last_step) and k not in commands)
    lat.sort()
    return {
        'samples': len(lat),
        'p50_us': _percentile(lat, 0.50), 'p90_us': _percentile(lat, 0.90),
        'p99_us': _percentile(lat, 0.99), 'max_us': lat[-1] if lat else None,
        'late_steps': len(late), 'missed_steps': len(missed),
        'late_first': late[:10], 'missed_first': missed[:10],
        'states': len(states), 'commands': len(commands),
    }


def main(argv=None) -> int:
    """Read the states and commands of the UHs ``--ids`` until SIGINT/SIGTERM or ``--last-step``; write the latencies.

    The summary per controller (:func:`summarise`) goes to ``--out`` as JSON; ``--ready`` is created
    once the readers exist. Return 0.
    """
    p = argparse.ArgumentParser(prog='uh_bench.probe', description=__doc__.split('\n\n')[0])
    p.add_argument('--domain-id', type=int, required=True)
    p.add_argument('--ids', required=True, help='UH ids: "1..20" or "1,2,5"')
    p.add_argument('--dt', type=float, default=0.01)
    p.add_argument('--last-step', type=int, default=None)
    p.add_argument('--out', required=True)
    p.add_argument('--ready', default=None, help='file to create once the readers exist')
    args = p.parse_args(argv)
    if '..' in args.ids:
        lo, hi = args.ids.split('..')
        ids = list(range(int(lo), int(hi) + 1))
    else:
        ids = [int(i) for i in args.ids.split(',') if i]

    from cyclonedds._clayer import ddspy_take
    from cyclonedds.core import GuardCondition, InstanceState, ReadCondition, SampleState, ViewState, WaitSet
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.qos import Policy, Qos
    from cyclonedds.sub import DataReader, Subscriber
    from cyclonedds.topic import Topic

    from uh_runtime import messages
    from uh_runtime.dds.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy, to_dds_qos

    dp = DomainParticipant(args.domain_id, qos=Qos(Policy.Userdata(b'enclave=/;')))
    sub = Subscriber(dp)
    profile = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100000,
                         reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    readers = []    # (reader, uh id, 'state'|'command')
    for kind, type_name in (('state', 'uh_msgs/msg/UHState'), ('command', 'uh_msgs/msg/ActuatorCommand')):
        cls = messages.dds_message(type_name)
        qos = to_dds_qos(profile, f'typehash={messages.type_hash(cls)};'.encode())
        for i in ids:
            topic = Topic(dp, f'rt/uh{i}/{kind}', cls)
            readers.append((DataReader(sub, topic, qos=qos), i, kind))
    waitset = WaitSet(dp)
    conditions = []
    for reader, _, _ in readers:
        cond = ReadCondition(reader, SampleState.NotRead | ViewState.Any | InstanceState.Any)
        waitset.attach(cond)
        conditions.append(cond)
    guard = GuardCondition(dp)
    waitset.attach(guard)
    stop = []

    def on_signal(signum, frame):
        stop.append(signum)
        guard.set(True)
    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    if args.ready:
        open(args.ready, 'w').close()

    mask = SampleState.Any | ViewState.Any | InstanceState.Any
    data = {i: {'state': {}, 'command': {}} for i in ids}
    dt = args.dt
    while not stop:
        waitset.wait(int(0.5e9))
        for reader, i, kind in readers:
            ret = ddspy_take(reader._ref, mask, 1024)
            if isinstance(ret, int):
                continue
            table = data[i][kind]
            for payload, info in ret:
                if not info.valid_data:
                    continue
                sec, nsec = _STAMP.unpack_from(payload, 4)
                k = int(round((sec + nsec * 1e-9) / dt))
                table.setdefault(k, info.source_timestamp)
        if args.last_step is not None and all(args.last_step in d['command'] for d in data.values()):
            break
    result = {'ids': ids, 'dt': dt, 'controllers': {
        str(i): summarise(d['state'], d['command'], args.last_step) for i, d in data.items()}}
    with open(args.out, 'w') as f:
        json.dump(result, f)
    del waitset
    dp.__del__()
    return 0


if __name__ == '__main__':
    sys.exit(main())
