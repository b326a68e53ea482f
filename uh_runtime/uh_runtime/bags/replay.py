"""``replay_node`` (behind ``scripts/replay.sh``): republish a recorded rosbag2 MCAP bag over DDS.

Like ``ros2 bag play --clock``: every message of the bag (or of the topics chosen) is published
again on its topic, with its recorded type, with the QoS its publishers offered when it was
recorded (the ``offered_qos_profiles`` of the bag's channel metadata), at its recorded log time
scaled by a rate factor, and with its payload bytes exactly as recorded (raw CDR, no decode and
re-encode). ``/clock`` is always published: the bag's own ``/clock`` messages when it has that
topic, otherwise a ``rosgraph_msgs/msg/Clock`` holding the log time, published just before the
first message of each new log time. So ``uh topic echo`` or ``ros2 topic echo``, RViz2, Foxglove
and nodes with ``use_sim_time`` see the run again.

Timing: message ``m`` is due at ``t_start + (log_time(m) - log_time(first)) / rate`` on the
monotonic clock; messages are sent in log-time order, ties in the order they are stored in the
file (the order they were recorded in). Log times of this project's bags are simulation times
(see :mod:`uh_runtime.bags.recorder`); those of ``ros2 bag record`` are receive times.

Bags are checked before anything is published (:func:`uh_runtime.bags.bag_reader.open_bag`): a missing
or empty directory, a file that is not MCAP, a file cut short (no footer: the recorder was killed),
a damaged summary or chunk (CRC mismatch) and unusable QoS metadata are reported as
:class:`~uh_runtime.bags.bag_reader.BagError` naming the file and what is wrong.

Exit status: 0 done, 1 nobody subscribed in time (``--wait-for-subscribers``), 2 bad arguments or
an unreadable bag, 130 interrupted (Ctrl-C, SIGTERM).
"""
from __future__ import annotations

import argparse
import math
import os
import signal
import socket
import subprocess
import sys
import time

import uh_runtime as rt
from uh_runtime import messages
from uh_runtime.bags import live_view
from uh_runtime.bags.bag_reader import BagError, BagInfo, iter_bag_messages, open_bag
from uh_runtime.command_line import ArgumentParser
from uh_runtime.dds.qos import QoSWords, profile_from_words
from uh_runtime.network import MAX_DOMAIN_ID, loopback_environment

__all__ = ['ReplayNode', 'build_parser', 'main']

PROG = 'replay'

#: How long ``--wait-for-subscribers`` waits for every replayed topic to have a subscriber, s.
WAIT_FOR_SUBSCRIBERS_TIMEOUT = 60.0


# ----------------------------------------------------------------------------------------------
# Message types the bag defines
# ----------------------------------------------------------------------------------------------
def _register_types_from_bag(info: BagInfo, names) -> None:
    """Make types the runtime does not know known from the bag's own ``ros2msg`` schemas.

    Those are types that are not uh_msgs and not a Jazzy standard type. Cyclone DDS backend only; rclpy
    imports installed types.
    """
    from rosbags.typesys import get_types_from_msg

    store = messages.typestore()
    for name in names:
        topic = info.topics[name]
        if topic.type in store.fielddefs:
            continue
        if not topic.definition.strip():
            raise BagError(f'{info.files[0]}: topic {name} has type {topic.type}, which this runtime '
                           'does not know, and the bag holds no definition of it')
        try:
            types = get_types_from_msg(topic.definition, topic.type)
            store.register({k: v for k, v in types.items() if k not in store.fielddefs})
        except Exception as exc:  # rosbags raises its own parse errors
            raise BagError(f'{info.files[0]}: the definition of {topic.type} (topic {name}) in the bag '
                           f'cannot be parsed ({type(exc).__name__}: {exc})') from None


# ----------------------------------------------------------------------------------------------
# The node
# ----------------------------------------------------------------------------------------------
class _Progress:
    """One status line on stderr, redrawn in place at most 4 times per second (terminal only)."""

    def __init__(self, stream, total_messages: int, duration_s: float, rate: float):
        self.stream, self.total, self.duration, self.rate = stream, total_messages, duration_s, rate
        self.tty = stream.isatty()
        self.last = 0.0

    def update(self, sent: int, bag_s: float, loop: int, force: bool = False) -> None:
        if not self.tty:
            return
        now = time.monotonic()
        if not force and now - self.last < 0.25:
            return
        self.last = now
        loop_text = f'  loop {loop}' if loop > 1 else ''
        self.stream.write(f'\r\033[K[replay] {bag_s:8.2f} / {self.duration:.2f} s bag time  '
                          f'{sent}/{self.total} messages  x{self.rate:g}{loop_text}')
        self.stream.flush()

    def close(self) -> None:
        if self.tty:
            self.stream.write('\n')
            self.stream.flush()


class ReplayNode(rt.Node):
    """The ``replay`` node: one publisher per replayed topic (and ``/clock``), then :meth:`play`.

    Parameters
    ----------
    info : BagInfo
        From :func:`open_bag`.
    topics : iterable of str, optional
        Topics to replay (``/clock`` is added when ``clock`` is true and the bag has it).
    clock : bool
        Publish ``/clock`` (the bag's, or synthesised from the log times if it has none).
    **node_kwargs
        Passed to ``Node`` (e.g. ``context``).

    Raises
    ------
    BagError
        A requested topic is not in the bag, or a type cannot be built.
    """

    def __init__(self, info: BagInfo, topics=None, clock: bool = True, **node_kwargs):
        wanted = list(info.topics) if not topics else list(dict.fromkeys(topics))
        unknown = [t for t in wanted if t not in info.topics]
        if unknown:
            raise BagError(f'{info.directory}: topic(s) {", ".join(unknown)} not in the bag; it has '
                           f'{", ".join(sorted(info.topics))}')
        if clock and '/clock' in info.topics and '/clock' not in wanted:
            wanted.append('/clock')
        if rt.BACKEND != 'rclpy':
            _register_types_from_bag(info, wanted)
        super().__init__('replay', **node_kwargs)
        self.bag_info = info
        self.replay_topics = wanted
        self.publishers_by_topic = {}
        for name in wanted:
            topic = info.topics[name]
            try:
                msg_type = messages.get_message(topic.type)
            except messages.MessageError as exc:
                raise BagError(f'{info.files[0]}: topic {name}: {exc}') from None
            self.publishers_by_topic[name] = self.create_publisher(
                msg_type, name, profile_from_words(topic.qos))
        self.synth_clock = None
        if clock and '/clock' not in info.topics:
            self.synth_clock = self.create_publisher(messages.get_message('rosgraph_msgs/msg/Clock'), '/clock',
                                                     profile_from_words(QoSWords()))
        self.sent = 0

    # -- waiting ------------------------------------------------------------------------
    def all_publishers(self) -> dict:
        """Return ``{topic: publisher}`` of every replayed topic, a synthesised ``/clock`` included."""
        pubs = dict(self.publishers_by_topic)
        if self.synth_clock is not None:
            pubs['/clock'] = self.synth_clock
        return pubs

    def wait_for_subscribers(self, timeout: float) -> list:
        """Wait until every publisher has a matched subscription; return the topics without one."""
        deadline = time.monotonic() + timeout
        while True:
            lonely = [t for t, p in self.all_publishers().items() if p.get_subscription_count() < 1]
            if not lonely or time.monotonic() >= deadline or not rt.ok():
                return lonely
            time.sleep(0.02)

    def _sleep_until(self, due: float, on_tick) -> bool:
        """Sleep until ``due`` (monotonic s) in short slices; False if the context shut down."""
        while True:
            if not rt.ok():
                return False
            remaining = due - time.monotonic()
            if remaining <= 0:
                return True
            on_tick()
            time.sleep(min(remaining, 0.05))

    def _publish_clock(self, ns: int) -> None:
        msg = self.synth_clock.msg_type()
        msg.clock.sec, msg.clock.nanosec = ns // 1_000_000_000, ns % 1_000_000_000
        self.synth_clock.publish(msg)

    # -- playing ------------------------------------------------------------------------
    def play(self, rate: float = 1.0, loop: bool = False, progress: _Progress | None = None) -> bool:
        """Publish the bag with its timing scaled by ``rate``; True when it ran to the end.

        Returns False when the context was shut down (SIGTERM) before the end; Ctrl-C raises
        ``KeyboardInterrupt`` out of it.
        """
        selected = list(self.replay_topics)
        loops = 0
        while True:
            loops += 1
            start_wall = None
            first_ns = None
            last_clock = None
            for topic, log_ns, data in iter_bag_messages(self.bag_info, selected):
                if start_wall is None:
                    start_wall, first_ns = time.monotonic(), log_ns
                due = start_wall + (log_ns - first_ns) * 1e-9 / rate
                tick = (lambda log_ns=log_ns, loops=loops: progress.update(
                    self.sent, (log_ns - self.bag_info.start_ns) * 1e-9, loops)) if progress else (lambda: None)
                if not self._sleep_until(due, tick):
                    return False
                if self.synth_clock is not None and log_ns != last_clock:
                    self._publish_clock(log_ns)
                    last_clock = log_ns
                self.publishers_by_topic[topic].publish(data)
                self.sent += 1
                if progress:
                    tick()
            if progress:
                progress.update(self.sent, self.bag_info.duration_s, loops, force=True)
            if not loop or start_wall is None:
                return True

    def flush(self, timeout: float = 2.0) -> None:
        """Wait until reliable subscribers acknowledged what was sent, ``timeout`` s at most in all."""
        deadline = time.monotonic() + timeout
        for pub in self.all_publishers().values():
            left = max(0.0, deadline - time.monotonic())
            try:
                pub.wait_for_all_acked(rt.Duration(seconds=left))
            except Exception:  # a best-effort topic or a backend without acks: nothing to wait for
                pass


# ----------------------------------------------------------------------------------------------
# Entry point
# ----------------------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``replay_node`` / ``scripts/replay.sh``."""
    p = ArgumentParser(
        prog=PROG,
        description='Republish a recorded rosbag2 MCAP bag over DDS with its original timing scaled by '
                    '--rate, its recorded QoS and its payload bytes as recorded, and /clock.',
        epilog='Example: scripts/replay.sh runs/proposed --rate 2 --topics /markers /uh1/state')
    p.add_argument('bag', metavar='RUN_DIR|BAG_DIR',
                   help='a run directory of run_formation.sh (its bag/), a rosbag2 MCAP bag directory, '
                        'or an .mcap file')
    p.add_argument('--rate', type=float, default=1.0,
                   help='bag seconds per wall second (default 1; 0.01 .. 1000)')
    p.add_argument('--loop', action='store_true', help='start again at the end (until Ctrl-C)')
    p.add_argument('--topics', nargs='+', metavar='T', default=None,
                   help='replay only these topics (and /clock); default: every topic of the bag')
    p.add_argument('--no-clock', action='store_true', help='do not publish /clock')
    p.add_argument('--domain-id', type=int, default=None,
                   help=f'DDS domain id 0..{MAX_DOMAIN_ID} (default: ROS_DOMAIN_ID, else 0)')
    p.add_argument('--delay', type=float, default=0.5,
                   help='s to wait after creating the publishers before the first message, so that '
                        'running subscribers discover them (default 0.5)')
    p.add_argument('--wait-for-subscribers', action='store_true',
                   help=f'start only once every replayed topic has a subscriber (at most '
                        f'{WAIT_FOR_SUBSCRIBERS_TIMEOUT:g} s, then exit 1)')
    live_view.add_arguments(p, 'the replayed topics')
    p.add_argument('--no-check', action='store_true',
                   help='skip the CRC check of every chunk before playing (faster start on huge bags)')
    return p


def _fail(message: str, status: int = 2) -> int:
    print(f'{PROG}: error: {message}', file=sys.stderr)
    return status


def _prepare(opts):
    """Check the options, open the bag and set the network up; return ``(domain, bag info)`` or an exit status."""
    if not opts.bag.strip():
        return _fail("RUN_DIR|BAG_DIR '': give a run directory, a bag directory or an .mcap file")
    if not (math.isfinite(opts.rate) and 0.01 <= opts.rate <= 1000):
        return _fail(f'--rate {opts.rate:g}: allowed 0.01 .. 1000 (bag seconds per wall second)')
    if not (math.isfinite(opts.delay) and opts.delay >= 0):
        return _fail(f'--delay {opts.delay:g}: allowed a finite number of seconds >= 0')
    domain = opts.domain_id
    if domain is None:
        env_domain = os.environ.get('ROS_DOMAIN_ID', '').strip()
        domain = int(env_domain) if env_domain.isdigit() else 0
    if not 0 <= domain <= MAX_DOMAIN_ID:
        return _fail(f'--domain-id {domain}: allowed 0..{MAX_DOMAIN_ID}')
    if opts.foxglove is not None:
        try:    # before anything starts
            live_view.check_available(opts.foxglove_host, opts.foxglove)
        except live_view.LiveViewError as exc:
            return _fail(str(exc))
    try:
        info = open_bag(opts.bag, check_chunks=not opts.no_check)
    except BagError as exc:
        return _fail(str(exc))
    if info.message_count == 0:
        return _fail(f'{info.files[0]}: the bag holds no messages')
    # same network set-up as run_formation.sh (uh_runtime.network.default_cyclonedds_uri)
    try:
        os.environ.update(loopback_environment(domain))
    except ValueError as exc:    # a bad ROS_AUTOMATIC_DISCOVERY_RANGE
        return _fail(str(exc))
    return domain, info


class _Session:
    """What a replay has started: its node, progress line and live view (None until started)."""

    def __init__(self):
        self.node = self.progress = self.viewer = None

    def close_progress(self) -> None:
        """End the progress line, if one is shown."""
        if self.progress:
            self.progress.close()
        self.progress = None

    def stop(self) -> None:
        """Destroy the node, shut the runtime down and stop the live view."""
        if self.node is not None:
            self.node.destroy_node()
        rt.try_shutdown()
        if self.viewer is not None:
            self.viewer.send_signal(signal.SIGINT)
            try:
                self.viewer.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.viewer.kill()


def _play(opts, info, domain: int, session: _Session) -> int:
    """Replay the bag as ``opts`` say (after the delay, or once every topic has a subscriber); return the status."""
    if opts.foxglove is not None:
        session.viewer = _start_live_view(opts.foxglove_host, opts.foxglove)
    node = session.node = ReplayNode(info, opts.topics, clock=not opts.no_clock)
    selected = node.replay_topics
    count = sum(info.topics[t].message_count for t in selected)
    clock_note = ('/clock from the bag' if '/clock' in selected else
                  'no /clock' if opts.no_clock else '/clock synthesised from log times')
    print(f'[replay] {info.directory}: {count} messages on {len(selected)} topics, '
          f'{info.duration_s:.2f} s of bag time at x{opts.rate:g} ({clock_note}), DDS domain {domain}',
          file=sys.stderr, flush=True)
    if opts.wait_for_subscribers:
        lonely = node.wait_for_subscribers(WAIT_FOR_SUBSCRIBERS_TIMEOUT)
        if lonely and rt.ok():
            return _fail(f'no subscriber within {WAIT_FOR_SUBSCRIBERS_TIMEOUT:g} s on {", ".join(lonely)}', 1)
    # the live view subscribes to what it discovers, every 0.2 s: give it a second
    deadline = time.monotonic() + (max(opts.delay, 1.0) if session.viewer else opts.delay)
    while rt.ok() and time.monotonic() < deadline:
        time.sleep(min(0.05, max(0.0, deadline - time.monotonic())))
    session.progress = _Progress(sys.stderr, count, info.duration_s, opts.rate)
    started = time.monotonic()
    finished = rt.ok() and node.play(opts.rate, opts.loop, session.progress)
    session.close_progress()
    if finished:
        node.flush()
        print(f'[replay] done: {node.sent} messages in {time.monotonic() - started:.2f} s wall',
              file=sys.stderr, flush=True)
        return 0
    print(f'[replay] stopped after {node.sent} messages', file=sys.stderr, flush=True)
    return 130


def main(args=None) -> int:
    """Entry point of ``replay_node`` / ``scripts/replay.sh``; returns the exit status."""
    argv = list(sys.argv if args is None else args)

    opts = build_parser().parse_args(rt.remove_ros_args(argv)[1:])
    prepared = _prepare(opts)
    if isinstance(prepared, int):
        return prepared
    domain, info = prepared
    # Ctrl-C stops the replay also when a shell started it in the background (which ignores SIGINT)
    signal.signal(signal.SIGINT, signal.default_int_handler)

    try:
        rt.init(args=argv)
    except Exception as exc:  # bad --ros-args
        return _fail(str(exc))
    session = _Session()
    try:
        status = _play(opts, info, domain, session)
    except BagError as exc:
        session.close_progress()
        status = _fail(str(exc))
    except (KeyboardInterrupt, rt.ExternalShutdownException):
        session.close_progress()
        node = session.node
        print(f'[replay] interrupted after {node.sent if node else 0} messages', file=sys.stderr, flush=True)
        status = 130
    finally:
        session.stop()
    return status


def _start_live_view(host: str, port: int):
    """Start the live view node (:mod:`uh_runtime.bags.live_view`) beside the replay, in its DDS domain.

    Return its process once it accepts connections.
    """
    viewer = subprocess.Popen([sys.executable, '-P', '-m', 'uh_runtime.bags.live_view', '--ros-args',
                               '-p', f'host:={host}', '-p', f'port:={port}'], env=dict(os.environ))
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline and viewer.poll() is None:
        try:
            socket.create_connection((host, port), timeout=0.5).close()
            print(f'[replay] live view: {live_view.connect_hint(host, port)}', file=sys.stderr, flush=True)
            return viewer
        except OSError:
            time.sleep(0.2)
    viewer.kill()
    raise BagError(f'the live view did not start on {host}:{port} (exit status {viewer.poll()})')


if __name__ == '__main__':
    sys.exit(main())
