"""Publish -> callback latency and throughput of the Cyclone DDS backend between two processes.

Not a test (no timing assertions anywhere): a measurement to run by hand::

    .venv/bin/python tests/helpers_runtime/bench_latency.py [--count 2000] [--domain-id 199]

Latency: ping-pong of UHState between two processes (``ping`` publishes, the echo process's
callback republishes on ``pong``, the ping process's callback stamps the arrival); one-way latency
is half the round trip, so it includes one serialisation, one deserialisation and one executor
wake-up per direction. Throughput: the ping process publishes ``--count`` messages back to back
(reliable, keep-all) and the echo process's callback counts them.
"""
import argparse
import os
import statistics
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))


def _rt():
    import uh_runtime as rt
    from uh_runtime.messages import UHState
    return rt, UHState


def echo_main():
    rt, UHState = _rt()
    rt.init(args=sys.argv)
    node = rt.Node('echo')
    qos = rt.QoSProfile(history=rt.HistoryPolicy.KEEP_ALL)
    pong = node.create_publisher(UHState, 'pong', qos)
    count = [0]

    def on_ping(msg):
        if msg.uh_id == 1:          # latency phase: answer at once
            pong.publish(msg)
        else:                       # throughput phase: count, answer the last one
            count[0] += 1
            if msg.step == 0:
                reply = UHState()
                reply.uh_id, reply.step = 2, count[0]
                pong.publish(reply)
    node.create_subscription(UHState, 'ping', on_ping, qos)
    try:
        rt.spin(node)
    except (KeyboardInterrupt, rt.ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rt.try_shutdown()


def ping_main(count):
    rt, UHState = _rt()
    rt.init(args=['bench'])
    node = rt.Node('ping')
    qos = rt.QoSProfile(history=rt.HistoryPolicy.KEEP_ALL)
    ping = node.create_publisher(UHState, 'ping', qos)
    arrivals = []
    node.create_subscription(UHState, 'pong', lambda m: arrivals.append((time.perf_counter(), m)), qos)
    executor = rt.SingleThreadedExecutor()
    executor.add_node(node)
    while ping.get_subscription_count() == 0 or node.count_publishers('pong') == 0:
        executor.spin_once(timeout_sec=0.1)
    time.sleep(0.5)  # let the echo process's reader match ours too (a benchmark, not a test)

    # latency
    rtts = []
    for k in range(count):
        msg = UHState()
        msg.uh_id, msg.step = 1, k
        msg.position.x = float(k)
        start = time.perf_counter()
        ping.publish(msg)
        while not arrivals:
            executor.spin_once(timeout_sec=1.0)
        stamp, back = arrivals.pop()
        assert back.step == k
        rtts.append(stamp - start)
    one_way = sorted(r / 2 * 1e6 for r in rtts)
    print(f'latency (one way, us) over {count} UHState: median {statistics.median(one_way):.0f}, '
          f'p90 {one_way[int(0.9 * len(one_way))]:.0f}, p99 {one_way[int(0.99 * len(one_way))]:.0f}, '
          f'max {one_way[-1]:.0f}')

    # throughput
    n = count * 5
    start = time.perf_counter()
    for k in range(n, -1, -1):
        msg = UHState()
        msg.uh_id, msg.step = 2, k
        ping.publish(msg)
    publish_done = time.perf_counter()
    while not arrivals:
        executor.spin_once(timeout_sec=5.0)
    end = time.perf_counter()
    received = arrivals[-1][1].step
    print(f'throughput: {received} of {n + 1} UHState received in {end - start:.3f} s '
          f'= {received / (end - start):.0f} msg/s (publishing alone: '
          f'{(n + 1) / (publish_done - start):.0f} msg/s)')
    node.destroy_node()
    rt.try_shutdown()


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--count', type=int, default=2000)
    parser.add_argument('--domain-id', type=int, default=199)
    parser.add_argument('--role', choices=['ping', 'echo'], default='ping', help=argparse.SUPPRESS)
    args, _ = parser.parse_known_args()
    if args.role == 'echo':
        return echo_main()
    from uh_runtime.network import loopback_environment
    env = loopback_environment(args.domain_id)
    os.environ.update(env)
    echo = subprocess.Popen([sys.executable, __file__, '--role', 'echo'], env=env)
    try:
        ping_main(args.count)
    finally:
        echo.terminate()
        echo.wait(timeout=10)


if __name__ == '__main__':
    main()
