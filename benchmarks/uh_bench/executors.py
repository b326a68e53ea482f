"""CPU per received message of the executors (docs/runtime.md#executors-on-rclpy).

A publisher process (always on the DDS backend, so it is the same for every case) sends
``UHState`` on 5 topics at 100 Hz each, spread over the period (one message per wake-up, as from
the team's separate processes); a subscriber process, on the backend and with the executor
of the case, counts the messages and measures its own CPU time over a fixed number of them:

``rclpy``
    rclpy's ``SingleThreadedExecutor`` (what ``rclpy.spin`` uses).
``rclpy-static``
    ``uh_runtime``'s ``StaticSingleThreadedExecutor`` on rclpy (what the project's nodes use).
``dds``
    the Cyclone DDS backend's executor.

    python -m uh_bench.executors            # all cases this Python can run, one line each
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

TOPICS = 5
RATE_HZ = 100.0  # per topic: the team's step rate
CASES = {'rclpy': ('rclpy', 'SingleThreadedExecutor'),
         'rclpy-static': ('rclpy', 'StaticSingleThreadedExecutor'),
         'dds': ('dds', 'StaticSingleThreadedExecutor')}


def _publish(seconds: float) -> None:
    import uh_runtime as rt
    from uh_runtime import messages as m
    rt.init()
    node = rt.Node('executor_bench_pub')
    pubs = [node.create_publisher(m.UHState, f'/bench{i}/state', 10) for i in range(TOPICS)]
    msg, period, end = m.UHState(), 1.0 / RATE_HZ, time.monotonic() + seconds
    tick = time.monotonic()
    while time.monotonic() < end:
        for i, pub in enumerate(pubs):  # spread over the period, as the team's senders are
            time.sleep(max(0.0, tick + i * period / TOPICS - time.monotonic()))
            pub.publish(msg)
        tick += period
    node.destroy_node()
    rt.try_shutdown()


def _subscribe(executor_name: str, messages: int) -> dict:
    import uh_runtime as rt
    from uh_runtime import messages as m
    rt.init()
    node = rt.Node('executor_bench_sub')
    count = [0]

    def received(_msg):
        count[0] += 1
    for i in range(TOPICS):
        node.create_subscription(m.UHState, f'/bench{i}/state', received, 10)
    executor = getattr(rt, executor_name)()
    executor.add_node(node)
    deadline = time.monotonic() + 60.0
    while count[0] < 50 and time.monotonic() < deadline:  # discovery and warm-up
        executor.spin_once(timeout_sec=0.1)
    cpu0, start, wall0 = time.process_time(), count[0], time.monotonic()
    while count[0] < start + messages and time.monotonic() < deadline + 60.0:
        executor.spin_once(timeout_sec=0.1)
    cpu, got, wall = time.process_time() - cpu0, count[0] - start, time.monotonic() - wall0
    executor.shutdown()
    node.destroy_node()
    rt.try_shutdown()
    return {'backend': rt.BACKEND, 'executor': executor_name, 'messages': got, 'wall_s': wall,
            'cpu_us_per_message': 1e6 * cpu / got if got else None}


def measure(case: str, messages: int = 2500) -> dict:
    """Run the publisher and the subscriber of ``case`` in a DDS domain of their own; return their result.

    ``case`` is a key of :data:`CASES`; the domain is reserved, on the loopback network, and given back.
    """
    from uh_runtime.network import loopback_environment, release_domain_id, reserve_domain_id
    domain = reserve_domain_id()
    try:
        return _measure(case, messages, loopback_environment(domain, dict(os.environ)))
    finally:
        release_domain_id(domain)


def _measure(case: str, messages: int, env: dict) -> dict:
    backend, executor_name = CASES[case]
    bench_dir = str(Path(__file__).resolve().parents[1])  # so the children import uh_bench
    env['PYTHONPATH'] = bench_dir + (os.pathsep + env['PYTHONPATH'] if env.get('PYTHONPATH') else '')
    seconds = 30.0 + messages / (TOPICS * RATE_HZ)
    pub = subprocess.Popen([sys.executable, '-P', '-m', 'uh_bench.executors', '--role', 'pub',
                            '--seconds', str(seconds)], env={**env, 'UH_BACKEND': 'dds'})
    try:
        sub = subprocess.run([sys.executable, '-P', '-m', 'uh_bench.executors', '--role', 'sub',
                              '--executor', executor_name, '--messages', str(messages)],
                             env={**env, 'UH_BACKEND': backend}, capture_output=True, text=True,
                             timeout=seconds + 60)
    finally:
        pub.kill()
        pub.wait()
    if sub.returncode != 0:
        raise RuntimeError(f'executor benchmark {case}: subscriber failed: {sub.stderr[-2000:]}')
    return {'case': case, **json.loads(sub.stdout.strip().splitlines()[-1])}


def main(argv=None) -> int:
    """Measure every executor case and print one JSON line each; return 0.

    ``--role pub`` / ``sub`` run the publisher or subscriber process of one case (used by :func:`measure`).
    """
    p = argparse.ArgumentParser(prog='python -m uh_bench.executors', description=__doc__.split('\n')[0])
    p.add_argument('--role', choices=('all', 'pub', 'sub'), default='all', help=argparse.SUPPRESS)
    p.add_argument('--seconds', type=float, default=60.0, help=argparse.SUPPRESS)
    p.add_argument('--executor', default='StaticSingleThreadedExecutor', help=argparse.SUPPRESS)
    p.add_argument('--messages', type=int, default=2500, help='messages measured per case')
    args = p.parse_args(argv)
    if args.role == 'pub':
        _publish(args.seconds)
    elif args.role == 'sub':
        print(json.dumps(_subscribe(args.executor, args.messages)))
    else:
        for case in CASES:
            print(json.dumps(measure(case, args.messages)))
    return 0


if __name__ == '__main__':
    sys.exit(main())
