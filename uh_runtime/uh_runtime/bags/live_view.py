"""Live view node (``live_view``): the team's topics over the Foxglove WebSocket protocol.

See docs/visualization.md#live-view-in-foxglove.

Follows every topic of the DDS domain like the recorder (:func:`uh_runtime.bags.recorder.new_topics`),
subscribes to it raw, and logs each CDR payload unchanged to a channel of a ``foxglove-sdk``
WebSocket server (``foxglove.websocket.v1``), with the type's ``ros2msg`` definition as the schema
(the same text a bag's MCAP schema holds, :func:`uh_runtime.bags.bag.message_definition`). The Foxglove
app connected to ``ws://HOST:PORT`` decodes them like a ROS 2 connection: 3-D scene from ``/tf``
and ``/markers``, plots, diagnostics.

The server is foxglove-sdk's: every client has its own bounded queue, and a slow or vanished
client only loses its own messages; a publisher of the team never waits for a viewer. Bound to
``127.0.0.1`` unless ``host`` says otherwise. Needs the optional ``foxglove-sdk`` package; on a
ROS 2 machine ``foxglove_bridge`` does the same job.
"""
from __future__ import annotations

import dataclasses
import errno
import socket
import threading
import time

import uh_runtime as rt
from uh_runtime import messages as m
from uh_runtime.bags.bag import message_definition
from uh_runtime.bags.bag_reader import BagError
from uh_runtime.bags.recorder import LogClock, new_topics, stamped_first
from uh_runtime.dds.qos import merge_offered, profile_from_words

__all__ = ['LiveViewNode', 'LiveViewError', 'add_arguments', 'check_available', 'check_port', 'connect_hint',
           'require_foxglove', 'main', 'DEFAULT_PORT']

DEFAULT_PORT = 8765
#: s to wait for viewers to close at shutdown
STOP_WAIT_S = 1.0
_DEPTH = 100


class LiveViewError(ValueError):
    """The live view cannot start (port, host or the foxglove-sdk package)."""


def check_port(host: str, port: int, names=('--foxglove port', '--foxglove-host')) -> None:
    """Raise :class:`LiveViewError` unless a TCP server can bind ``host:port`` now.

    ``names`` are how the messages name the port and the host: the options, or a node's parameters.
    """
    if not 1 <= int(port) <= 65535:
        raise LiveViewError(f'{names[0]} {port}: allowed 1..65535')
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except socket.gaierror as exc:
        raise LiveViewError(f'{names[1]} {host!r}: cannot resolve it ({exc.strerror})') from None
    family, kind, proto, _, address = infos[0]
    with socket.socket(family, kind, proto) as sock:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind(address)
        except OSError as exc:
            why = 'in use by another program' if exc.errno == errno.EADDRINUSE else exc.strerror
            raise LiveViewError(f'cannot serve the live view on {host}:{port}: {why}; choose another '
                                f'port with --foxglove PORT') from None


def require_foxglove():
    """Return the ``foxglove`` module (foxglove-sdk); raise :class:`LiveViewError` saying how to install it."""
    try:
        import foxglove
    except ImportError:
        raise LiveViewError('the live view needs the foxglove-sdk package: pip install -r requirements.txt '
                            '(on a ROS 2 machine use foxglove_bridge instead, docs/visualization.md)') from None
    return foxglove


def check_available(host: str, port: int) -> None:
    """Everything a live view needs before anything starts: foxglove-sdk, and ``host:port`` free."""
    require_foxglove()
    check_port(host, port)


def connect_hint(host: str, port: int) -> str:
    """Return what a user types into Foxglove to see the live view."""
    return (f'ws://{host}:{port}   (Foxglove: Open connection, Foxglove WebSocket; '
            'docs/visualization.md#live-view-in-foxglove)')


def add_arguments(parser, what: str) -> None:
    """Add ``--foxglove [PORT]`` and ``--foxglove-host HOST`` to ``parser``.

    These are the options of the command-line tools that offer the live view; ``what`` names what is served
    (e.g. 'the team').
    """
    parser.add_argument('--foxglove', nargs='?', type=int, const=DEFAULT_PORT, default=None, metavar='PORT',
                        help=f'serve {what} live over the Foxglove WebSocket protocol on ws://HOST:PORT '
                             f'(default port {DEFAULT_PORT}; docs/visualization.md#live-view-in-foxglove); '
                             'needs foxglove-sdk')
    parser.add_argument('--foxglove-host', default='127.0.0.1', metavar='HOST',
                        help='address the live view binds (default 127.0.0.1; 0.0.0.0 exposes it to the network)')


class LiveViewNode(rt.Node):
    """See the module docstring. Parameters: ``host``, ``port``, ``topics`` (empty: all).

    Keyword arguments go to ``Node`` (e.g. ``parameter_overrides``). Raises :class:`LiveViewError`
    without foxglove-sdk or when the port cannot be bound.
    """

    def __init__(self, **kwargs):
        super().__init__('live_view', **kwargs)
        self.declare_parameter('host', '127.0.0.1', rt.ParameterDescriptor(
            description='address the WebSocket server binds (0.0.0.0: every interface)', read_only=True))
        self.declare_parameter('port', DEFAULT_PORT, rt.ParameterDescriptor(
            description='TCP port of the WebSocket server', read_only=True))
        self.declare_parameter('topics', [''], rt.ParameterDescriptor(
            description='topics to serve; empty serves every topic discovered', read_only=True))
        host, port = str(self.get_parameter('host').value), int(self.get_parameter('port').value)
        self.wanted = {t for t in self.get_parameter('topics').value if t}
        foxglove = require_foxglove()
        check_port(host, port, names=("parameter 'port'", "parameter 'host'"))
        self._foxglove = foxglove
        self.channels = {}
        self.subscriptions_by_topic = {}
        self.log_clock = LogClock()
        self.logged = 0
        self.server = foxglove.start_server(name='uh team', host=host, port=port)  # last: destroy_node needs the rest
        self.get_logger().info(f'live view: {connect_hint(host, self.server.port)}')
        self.create_timer(0.2, self.discover)
        self.discover()

    def discover(self) -> None:
        """Serve every wanted topic that has appeared since the last look."""
        for name, type_name, offered in new_topics(self, self.subscriptions_by_topic, self.wanted):
            try:
                message_class = m.get_message(type_name)
                definition = message_definition(type_name)[0]
            except (LookupError, ValueError, BagError) as exc:  # a type this machine does not know: not served
                self.subscriptions_by_topic[name] = None
                self.get_logger().warning(f'not serving {name}: {exc}')
                continue
            schema = self._foxglove.Schema(name=type_name, encoding='ros2msg', data=definition.encode())
            channel = self.channels[name] = self._foxglove.Channel(name, schema=schema, message_encoding='cdr')
            stamped = stamped_first(type_name)
            # volatile: a viewer wants what comes from now on, not a replay of the writers' history
            words = dataclasses.replace(merge_offered(offered), durability='volatile', history='keep_last',
                                        depth=_DEPTH)
            self.subscriptions_by_topic[name] = self.create_subscription(
                message_class, name,
                lambda data, channel=channel, stamped=stamped, name=name: self.on_message(name, channel, data,
                                                                                          stamped),
                profile_from_words(words), raw=True)
            self.get_logger().info(f'serving {name} [{type_name}]')

    def on_message(self, name: str, channel, data: bytes, stamped: bool) -> None:
        """Log the CDR bytes ``data`` of topic ``name`` on its Foxglove ``channel``.

        The log time is that of :class:`~uh_runtime.bags.recorder.LogClock` (ns), wall time for an unstamped
        message before the first ``/clock``.
        """
        log_ns = self.log_clock.of(name, data, stamped)
        if not stamped and not log_ns:   # unstamped, before the first /clock: wall time
            log_ns = time.time_ns()
        channel.log(bytes(data), log_time=log_ns)
        self.logged += 1

    def destroy_node(self):
        """Stop the server (waiting at most :data:`STOP_WAIT_S` s for the viewers), log the count, destroy the node."""
        if hasattr(self, 'server'):
            # stopping closes every connection gracefully, which waits for a client that does not
            # read: give it STOP_WAIT_S, then leave (the process exit closes the sockets)
            stopper = threading.Thread(target=self.server.stop, daemon=True)
            stopper.start()
            stopper.join(STOP_WAIT_S)
            rt.log_on_exit(self, f'live view stopped: {self.logged} messages on {len(self.channels)} topics'
                           + ('' if not stopper.is_alive() else
                              f' (a viewer did not close within {STOP_WAIT_S:g} s: dropped)'))
        return super().destroy_node()


def main(args=None):
    """Console script ``live_view_node``: run :class:`LiveViewNode` (:func:`uh_runtime.run_node`)."""
    rt.run_node(LiveViewNode, args, user_errors=(LiveViewError,))


if __name__ == '__main__':
    main()
