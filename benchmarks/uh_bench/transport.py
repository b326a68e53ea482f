"""What one message costs on this machine: the floor under every distributed figure.

Three ping-pong measurements of a ``UHState``-sized message (132 bytes), each reporting the round
trip and the CPU the echoing side spends per message (read from ``/proc/<pid>/stat``, all its
threads, user and kernel):

- ``udp``: two processes bouncing a datagram over loopback sockets (kernel and scheduler only);
- ``dds``: the echo is a node of this stack (:mod:`uh_runtime`, the per-step QoS of the team:
  reliable, transient-local, keep-last 100) in a process of its own, as in the one-process-per-node
  layout: Cyclone DDS's receive thread, the wait set hand-over, take, deserialisation, the
  callback, serialisation and the write;
- ``in-process``: publisher and subscription in one process (the composed layouts): ``publish``
  then ``spin_once`` running the callback, no kernel involved.

and, with :func:`fanout`, what one ``publish`` costs the publishing thread when 0, 1, 3 or 6 node
processes subscribe (the publishes are spaced 0.5 ms apart, as in a run, so every one wakes the
readers; the figure with no remote reader includes that sleep and is the baseline of the others).

``python -P -m uh_bench.transport --echo DOMAIN`` is the echo process of ``dds``,
``--reader DOMAIN`` a subscriber of :func:`fanout`.
"""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

__all__ = ['udp_pingpong', 'dds_pingpong', 'inprocess_delivery', 'fanout', 'measure']

_PAYLOAD = 132


def _proc_cpu_s(pid: int) -> float:
    with open(f'/proc/{pid}/stat') as f:
        fields = f.read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def udp_pingpong(n: int = 20000) -> dict:
    """Round trip and the echo process's CPU per message over loopback UDP (no DDS, no Python work)."""
    a = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    b = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    a.bind(('127.0.0.1', 0))
    b.bind(('127.0.0.1', 0))
    pa, pb = a.getsockname(), b.getsockname()
    pid = os.fork()
    if pid == 0:  # echo
        try:
            for _ in range(n + 1):
                data, _ = b.recvfrom(2048)
                b.sendto(data, pa)
        finally:
            os._exit(0)
    msg = b'x' * _PAYLOAD
    try:
        a.sendto(msg, pb)
        a.recvfrom(2048)
        c0 = _proc_cpu_s(pid)
        t0 = time.perf_counter()
        for _ in range(n):
            a.sendto(msg, pb)
            a.recvfrom(2048)
        rtt = (time.perf_counter() - t0) / n
        c1 = _proc_cpu_s(pid)
    except BaseException:
        os.kill(pid, signal.SIGKILL)   # the echo would wait for ever
        raise
    finally:
        os.waitpid(pid, 0)
        a.close()
        b.close()
    return {'round_trip_us': rtt * 1e6, 'echo_cpu_us_per_message': (c1 - c0) * 1e6 / n, 'messages': n}


def _spin_until_stopped(node) -> int:
    """Spin ``node`` until the process is told to stop (SIGTERM or Ctrl-C), then clean up."""
    import uh_runtime as rt
    try:
        rt.spin(node)
    except (KeyboardInterrupt, rt.ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rt.try_shutdown()
    return 0


def _echo_main(domain: int) -> int:
    import uh_runtime as rt
    from uh_runtime import messages as m
    from uh_wire import topics
    rt.init(args=['uh_bench_echo'], domain_id=domain)
    node = rt.Node('echo')
    qos = topics.qos_profile(topics.STEP_QOS)
    pong = node.create_publisher(m.UHState, '/bench/pong', qos)
    node.create_subscription(m.UHState, '/bench/ping', pong.publish, qos)
    return _spin_until_stopped(node)


def dds_pingpong(domain: int, n: int = 5000) -> dict:
    """Round trip and the echo node process's CPU per message through the node runtime and Cyclone DDS."""
    import uh_runtime as rt
    from uh_runtime import messages as m
    from uh_runtime.network import loopback_environment
    from uh_wire import topics
    env = loopback_environment(domain)
    env['PYTHONPATH'] = str(Path(__file__).resolve().parents[1]) + (
        os.pathsep + env['PYTHONPATH'] if env.get('PYTHONPATH') else '')
    os.environ.setdefault('CYCLONEDDS_URI', env['CYCLONEDDS_URI'])   # this process joins on loopback too
    echo = subprocess.Popen([sys.executable, '-P', '-m', 'uh_bench.transport', '--echo', str(domain)], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    context = None
    try:
        context = rt.Context()
        rt.init(args=['uh_bench_ping'], context=context, domain_id=domain)
        node = rt.Node('ping', context=context)
        qos = topics.qos_profile(topics.STEP_QOS)
        ping = node.create_publisher(m.UHState, '/bench/ping', qos)
        got = []
        node.create_subscription(m.UHState, '/bench/pong', got.append, qos)
        executor = rt.SingleThreadedExecutor(context=context)
        executor.add_node(node)
        deadline = time.monotonic() + 30
        msg = m.UHState()
        while not got:   # until the echo answers (discovery both ways)
            if time.monotonic() > deadline or echo.poll() is not None:
                raise RuntimeError('the echo process did not answer within 30 s')
            ping.publish(msg)
            executor.spin_once(timeout_sec=0.1)
        time.sleep(0.2)
        executor.spin_once(timeout_sec=0)
        got.clear()
        c0 = _proc_cpu_s(echo.pid)
        t0 = time.perf_counter()
        for k in range(n):
            msg.step = k
            ping.publish(msg)
            while not got:
                executor.spin_once(timeout_sec=1.0)
            got.clear()
        rtt = (time.perf_counter() - t0) / n
        c1 = _proc_cpu_s(echo.pid)
        node.destroy_node()
    finally:
        if context is not None:
            context.try_shutdown()
        echo.terminate()
        try:
            echo.wait(timeout=10)
        except subprocess.TimeoutExpired:
            echo.kill()
            echo.wait()
    return {'round_trip_us': rtt * 1e6, 'echo_cpu_us_per_message': (c1 - c0) * 1e6 / n, 'messages': n}


def inprocess_delivery(domain: int, n: int = 20000) -> dict:
    """CPU per message when publisher and subscription share a process: publish, then spin_once."""
    import uh_runtime as rt
    from uh_runtime import messages as m
    from uh_runtime.network import loopback_config
    from uh_wire import topics
    os.environ.setdefault('CYCLONEDDS_URI', loopback_config())
    context = rt.Context()
    rt.init(args=['uh_bench_local'], context=context, domain_id=domain)
    try:
        node = rt.Node('local', context=context)
        qos = topics.qos_profile(topics.STEP_QOS)
        pub = node.create_publisher(m.UHState, '/bench/local', qos)
        got = []
        node.create_subscription(m.UHState, '/bench/local', got.append, qos)
        executor = rt.SingleThreadedExecutor(context=context)
        executor.add_node(node)
        msg = m.UHState()
        for _ in range(200):
            pub.publish(msg)
            executor.spin_once(timeout_sec=0)
        c0 = time.process_time()
        t0 = time.perf_counter()
        for _ in range(n):
            pub.publish(msg)
            executor.spin_once(timeout_sec=0)
        wall = (time.perf_counter() - t0) / n
        cpu = (time.process_time() - c0) / n
        node.destroy_node()
    finally:
        context.try_shutdown()
    return {'wall_us_per_message': wall * 1e6, 'cpu_us_per_message': cpu * 1e6, 'messages': n,
            'received': len(got)}


def _reader_main(domain: int) -> int:
    import uh_runtime as rt
    from uh_runtime import messages as m
    from uh_wire import topics
    rt.init(args=['uh_bench_reader'], domain_id=domain)
    node = rt.Node('reader')
    node.create_subscription(m.UHState, '/bench/fanout', lambda msg: None, topics.qos_profile(topics.STEP_QOS))
    return _spin_until_stopped(node)


def fanout(domain: int, counts=(0, 1, 3, 6), n: int = 2000) -> dict:
    """``{readers: publishing thread's CPU us per publish}`` with that many subscriber processes."""
    import uh_runtime as rt
    from uh_runtime import messages as m
    from uh_runtime.network import loopback_environment
    from uh_wire import topics
    env = loopback_environment(domain)
    env['PYTHONPATH'] = str(Path(__file__).resolve().parents[1]) + (
        os.pathsep + env['PYTHONPATH'] if env.get('PYTHONPATH') else '')
    os.environ.setdefault('CYCLONEDDS_URI', env['CYCLONEDDS_URI'])
    out = {}
    for count in counts:
        readers = []
        context = None
        try:
            for _ in range(count):
                readers.append(subprocess.Popen(
                    [sys.executable, '-P', '-m', 'uh_bench.transport', '--reader', str(domain)],
                    env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
            context = rt.Context()
            rt.init(args=['uh_bench_fanout'], context=context, domain_id=domain)
            node = rt.Node('writer', context=context)
            pub = node.create_publisher(m.UHState, '/bench/fanout', topics.qos_profile(topics.STEP_QOS))
            deadline = time.monotonic() + 60
            while pub.get_subscription_count() < count:
                if time.monotonic() > deadline:
                    raise RuntimeError(f'only {pub.get_subscription_count()} of {count} readers matched in 60 s')
                time.sleep(0.05)
            time.sleep(0.5)
            msg = m.UHState()
            c0 = time.thread_time()
            for k in range(n):
                msg.step = k
                pub.publish(msg)
                time.sleep(0.0005)
            out[count] = (time.thread_time() - c0) * 1e6 / n
            node.destroy_node()
        finally:
            if context is not None:
                context.try_shutdown()
            for proc in readers:
                proc.send_signal(signal.SIGINT)
            for proc in readers:
                try:
                    proc.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
    return out


def measure(domain: int, quick: bool = False) -> dict:
    """All the measurements (fewer messages, and no fan-out, when ``quick``)."""
    from uh_runtime.network import release_domain_id, reserve_domain_id
    scale = 4 if quick else 1
    other = reserve_domain_id()   # the in-process measurement's own domain
    try:
        result = {'udp': udp_pingpong(20000 // scale), 'dds': dds_pingpong(domain, 8000 // scale),
                  'inprocess': inprocess_delivery(other, 20000 // scale)}
        if not quick:
            result['fanout_cpu_us_per_publish'] = fanout(domain)
    finally:
        release_domain_id(other)
    return result


if __name__ == '__main__':
    if len(sys.argv) == 3 and sys.argv[1] == '--echo':
        sys.exit(_echo_main(int(sys.argv[2])))
    if len(sys.argv) == 3 and sys.argv[1] == '--reader':
        sys.exit(_reader_main(int(sys.argv[2])))
    import json
    print(json.dumps(measure(int(sys.argv[1]) if len(sys.argv) > 1 else 201, quick=True), indent=1))
