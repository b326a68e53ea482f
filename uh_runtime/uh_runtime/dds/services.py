"""Service servers of the Cyclone DDS backend, and the parameter services every node has.

The parameter services and ``/parameter_events`` have rclpy's (Jazzy) behaviour, so
``ros2 param list/get/set/describe`` and ``ros2 topic echo /parameter_events`` work on a node of either
backend (docs/runtime.md#parameters).

Wire conventions (rmw_cyclonedds_cpp, Jazzy):

- service ``/uh1/controller/list_parameters`` is a request topic ``rq/uh1/controller/list_parametersRequest``
  and a reply topic ``rr/uh1/controller/list_parametersReply``, of DDS types
  ``rcl_interfaces::srv::dds_::ListParameters_Request_`` and ``..._Response_``;
- each sample starts with the request header, ``uint64`` client writer instance and ``int64``
  sequence number, which the reply echoes (:func:`uh_runtime.messages.dds_service_message`);
- USER_DATA ``serviceid=<id>;typehash=RIHS01_<hex>;`` on the request reader and the reply writer
  (the same id on both, so a client pairs them), the request's and the response's own type hashes;
- before replying, the server waits (at most :data:`REPLY_MATCH_WAIT_S`) until its reply writer
  has matched the reader of the client that sent the request (``clientid=`` in that client's
  USER_DATA), as rmw_cyclonedds does, so the first reply to a new client is not lost.

Requests are served in the executor's thread, like subscription callbacks.
"""
from __future__ import annotations

import itertools
import time

from .. import messages as _messages
from ..names import REPLY_PREFIX, REQUEST_PREFIX
from .binding import matched_publication_data, matched_publications, matched_subscription_data, matched_subscriptions
from .clock import Clock, ClockType
from .context import typehash_user_data
from .parameters import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    Parameter,
    ParameterDescriptor,
    ParameterNotDeclaredException,
    ParameterType,
    ParameterUninitializedException,
    SetParametersResult,
)
from .qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy, to_dds_qos

__all__ = ['Service', 'ServiceClient', 'ParameterServices', 'parameter_value', 'value_message',
           'qos_profile_parameters', 'qos_profile_parameter_events', 'REPLY_MATCH_WAIT_S',
           'FOREIGN_CLIENT_CHECK_S', 'FOREIGN_CLIENT_TEXT']

#: rmw_qos_profile_parameters (services) and rmw_qos_profile_parameter_events: keep last 1000,
#: reliable, volatile.
qos_profile_parameters = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                                    reliability=ReliabilityPolicy.RELIABLE,
                                    durability=DurabilityPolicy.VOLATILE)
qos_profile_parameter_events = qos_profile_parameters

#: Longest wait for the client's reply reader before a reply is sent anyway, s.
REPLY_MATCH_WAIT_S = 0.5

_service_ids = itertools.count(1)

#: Period of a node's look for parameter clients it cannot answer, s of wall-clock time.
FOREIGN_CLIENT_CHECK_S = 1.0

#: What a node says, once, when such a client appears (docs/ros2.md#parameters-from-fast-dds).
FOREIGN_CLIENT_TEXT = (
    'a parameter client on {service} sends requests this node cannot answer: it is not rmw_cyclonedds '
    '(likely Fast DDS, ROS 2 Jazzy\'s default), whose requests carry no request header in their payload and '
    'whose replies are matched by a sample identity this backend cannot send (ros2/rmw_cyclonedds#184); '
    'run ros2 param with RMW_IMPLEMENTATION=rmw_cyclonedds_cpp, or use `uh param`')


def _user_data_value(endpoint, key: str) -> str | None:
    """Value of ``key=`` in the USER_DATA of a discovered endpoint (``DcpsEndpoint``), or None."""
    from cyclonedds.core import Policy
    try:
        data = endpoint.qos[Policy.Userdata].data
    except (KeyError, AttributeError, TypeError):
        return None
    for item in bytes(data).decode(errors='replace').split(';'):
        name, sep, value = item.partition('=')
        if sep and name == key:
            return value
    return None


def _endpoints(context, srv_type: str, srv_name: str, qos_profile, role: str):
    """Return what the request and the reply endpoints of ``srv_name`` need.

    Each is ``((publisher or subscriber entity, DDS topic, qos=...) arguments, sample class)``; the
    server reads requests and writes replies, the client the other way round. Both carry ``<role>=<id>;``
    (``serviceid`` or ``clientid``, an id unique to this pair) before the type hash in USER_DATA, as
    rmw_cyclonedds.
    """
    ident = '.'.join(f'{b:x}' for b in bytes(context.gid[:12]) + next(_service_ids).to_bytes(4, 'big'))
    extra = f'{role}={ident};'.encode()
    out = []
    for prefix, part, suffix in ((REQUEST_PREFIX, 'Request', 'Request'), (REPLY_PREFIX, 'Response', 'Reply')):
        cls = _messages.dds_service_message(f'{srv_type}_{part}')
        serves = (role == 'serviceid') == (part == 'Request')    # the server reads requests
        entity = context._sub if serves else context._pub
        qos = to_dds_qos(qos_profile, extra + typehash_user_data(cls))
        out.append(((entity, context.topic(f'{prefix}{srv_name}{suffix}', cls), qos), cls))
    return out


class Service:
    """A service server (``rclpy.service.Service`` subset).

    ``callback(request, response)`` returns the response; ``srv_type`` is ``'pkg/srv/Name'`` (one of
    :data:`uh_runtime.messages.SERVICE_DEFINITIONS`). Made by :meth:`Node.create_service
    <uh_runtime.dds.node.Node.create_service>` of ``node``: ``srv_name`` is resolved as a
    topic name of the node, ``qos_profile`` is that of the request reader and the reply writer.
    """

    def __init__(self, node, srv_type: str, srv_name: str, callback, qos_profile):
        from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState
        from cyclonedds.pub import DataWriter
        from cyclonedds.sub import DataReader
        self._node = node
        self.srv_type = srv_type
        self.callback = self._serve
        self._handler = callback
        self.srv_name = node.resolve_topic_name(srv_name)
        self.topic_name = self.srv_name          # what the executor names in its errors
        # the same id on the request reader and the reply writer: a client pairs them by it
        request, reply = _endpoints(node._context, srv_type, self.srv_name, qos_profile, 'serviceid')
        self._request_cls, self._response_cls = request[1], reply[1]
        self._reader = DataReader(*request[0])
        self._writer = DataWriter(*reply[0])
        self._condition = ReadCondition(self._reader, SampleState.NotRead | ViewState.Any | InstanceState.Any)
        self.gid = self._reader.get_guid().bytes
        self.writer_gid = self._writer.get_guid().bytes
        self._writers_seen = set()     # request writers looked at by clients_without_header

    def _take_messages(self, from_dds=True):
        """Every waiting request (samples with their info)."""
        if not from_dds:
            return []
        return [s for s in self._reader.take(N=64) if s.sample_info.valid_data]

    def _client_reader_matched(self, publication_handle) -> bool | None:
        """Return whether the reply writer has matched the reader of a client.

        The client is the one whose request writer is ``publication_handle``; None if that client is gone or
        does not say who it is.
        """
        try:
            writer = matched_publication_data(self._reader, publication_handle)
        except Exception:
            return None
        client = _user_data_value(writer, 'clientid') if writer is not None else None
        if client is None:
            return None
        for handle in matched_subscriptions(self._writer):
            try:
                reader = matched_subscription_data(self._writer, handle)
            except Exception:
                continue
            if reader is not None and _user_data_value(reader, 'clientid') == client:
                return True
        return False

    def clients_without_header(self) -> list:
        """Return the handles of the matched request writers that do not say ``clientid=`` (not met before).

        rmw_cyclonedds clients (and this backend's) say who they are in USER_DATA and put the request
        header in the payload; a client that does neither (Fast DDS, Jazzy's default RMW) sends requests
        this reader cannot read.
        """
        found = []
        for handle in matched_publications(self._reader):
            if handle in self._writers_seen:
                continue
            self._writers_seen.add(handle)
            try:
                writer = matched_publication_data(self._reader, handle)
            except Exception:
                continue
            if writer is not None and _user_data_value(writer, 'clientid') is None:
                found.append(handle)
        return found

    def _serve(self, request) -> None:
        response = self._response_cls()
        try:
            response = self._handler(request, response)
        except Exception as exc:   # a bad request must not take the node down
            self._node.get_logger().error(f'service {self.srv_name}: request not served: {exc}')
            return
        response.client_guid = request.client_guid
        response.sequence_number = request.sequence_number
        deadline = time.monotonic() + REPLY_MATCH_WAIT_S
        while self._client_reader_matched(request.sample_info.publication_handle) is False \
                and time.monotonic() < deadline:
            time.sleep(0.01)
        self._writer.write(response)

    def destroy(self):
        """Destroy the service through its node, as rclpy's ``Service.destroy`` does."""
        self._node.destroy_service(self)


# -- parameter services -------------------------------------------------------------------------
def value_message(value, type_=None):
    """``rcl_interfaces/msg/ParameterValue`` of a Python value."""
    cls = _messages.dds_message('rcl_interfaces/msg/ParameterValue')
    ptype = ParameterType.from_parameter_value(value) if type_ is None else type_
    msg = cls(type=int(ptype))
    field = {ParameterType.BOOL: 'bool_value', ParameterType.INTEGER: 'integer_value',
             ParameterType.DOUBLE: 'double_value', ParameterType.STRING: 'string_value',
             ParameterType.BYTE_ARRAY: 'byte_array_value', ParameterType.BOOL_ARRAY: 'bool_array_value',
             ParameterType.INTEGER_ARRAY: 'integer_array_value',
             ParameterType.DOUBLE_ARRAY: 'double_array_value',
             ParameterType.STRING_ARRAY: 'string_array_value'}.get(ptype)
    if field == 'byte_array_value':
        value = list(bytes(value)) if isinstance(value, (bytes, bytearray)) else [bytes(v)[0] for v in value]
    if field is not None:
        setattr(msg, field, list(value) if isinstance(value, (list, tuple)) else value)
    return msg


def parameter_value(msg):
    """Python value of an ``rcl_interfaces/msg/ParameterValue`` (None for NOT_SET)."""
    ptype = ParameterType(int(msg.type))
    if ptype == ParameterType.NOT_SET:
        return None
    field = {ParameterType.BOOL: 'bool_value', ParameterType.INTEGER: 'integer_value',
             ParameterType.DOUBLE: 'double_value', ParameterType.STRING: 'string_value',
             ParameterType.BYTE_ARRAY: 'byte_array_value', ParameterType.BOOL_ARRAY: 'bool_array_value',
             ParameterType.INTEGER_ARRAY: 'integer_array_value',
             ParameterType.DOUBLE_ARRAY: 'double_array_value',
             ParameterType.STRING_ARRAY: 'string_array_value'}[ptype]
    value = getattr(msg, field)
    if ptype == ParameterType.BYTE_ARRAY:
        return [bytes([b]) for b in value]
    return list(value) if isinstance(value, (list, tuple)) else value


def _parameter_msg(param):
    cls = _messages.dds_message('rcl_interfaces/msg/Parameter')
    return cls(name=param.name, value=value_message(param.value, param.type_))


def _descriptor_msg(descriptor: ParameterDescriptor):
    cls = _messages.dds_message('rcl_interfaces/msg/ParameterDescriptor')
    fp = _messages.dds_message('rcl_interfaces/msg/FloatingPointRange')
    ir = _messages.dds_message('rcl_interfaces/msg/IntegerRange')
    return cls(name=descriptor.name, type=int(descriptor.type), description=descriptor.description,
               additional_constraints=descriptor.additional_constraints, read_only=bool(descriptor.read_only),
               dynamic_typing=bool(descriptor.dynamic_typing),
               floating_point_range=[fp(from_value=float(r.from_value), to_value=float(r.to_value),
                                        step=float(r.step)) for r in descriptor.floating_point_range],
               integer_range=[ir(from_value=int(r.from_value), to_value=int(r.to_value), step=int(r.step))
                              for r in descriptor.integer_range])


def _result_msg(result: SetParametersResult):
    cls = _messages.dds_message('rcl_interfaces/msg/SetParametersResult')
    return cls(successful=bool(result.successful), reason=str(result.reason))


def _listed(name: str, prefixes: list, depth: int) -> bool:
    """Return whether ``list_parameters`` with ``prefixes`` and ``depth`` lists parameter ``name``.

    ``depth`` 0 is DEPTH_RECURSIVE; the rule is rclpy's (``Node.list_parameters``).
    """
    def shallow(part):
        return depth == 0 or part.count('.') < depth
    if not prefixes:
        return shallow(name)
    return any(name == p or (name.startswith(p + '.') and shallow(name[len(p) + 1:])) for p in prefixes)


class ParameterServices:
    """Counterpart of rclpy's ``ParameterService`` and parameter-event publisher for a DDS-backend node.

    The six services ``<node>/describe_parameters``, ``get_parameters``, ``get_parameter_types``,
    ``list_parameters``, ``set_parameters``, ``set_parameters_atomically``, answered as
    ``rclpy.parameter_service`` answers them, and a ``ParameterEvent`` on ``/parameter_events``
    for every declaration and every accepted change (``new_parameters`` /
    ``changed_parameters``), for ``node``; the services start with :meth:`start_services`.
    """

    SERVICES = (('describe_parameters', 'DescribeParameters'), ('get_parameters', 'GetParameters'),
                ('get_parameter_types', 'GetParameterTypes'), ('list_parameters', 'ListParameters'),
                ('set_parameters', 'SetParameters'),
                ('set_parameters_atomically', 'SetParametersAtomically'))

    def __init__(self, node):
        self._node = node
        self._events = node.create_publisher(
            _messages.dds_message('rcl_interfaces/msg/ParameterEvent'), '/parameter_events',
            qos_profile_parameter_events)

    def start_services(self):
        """Create the six services (rclpy does at the end of the node's constructor).

        Every :data:`FOREIGN_CLIENT_CHECK_S` of wall-clock time the node looks for clients whose
        requests it cannot read (:meth:`Service.clients_without_header`) and says so once.
        """
        node = self._node
        self._services = [node.create_service(f'rcl_interfaces/srv/{srv}', f'{node.get_name()}/{suffix}',
                                              getattr(self, f'_{suffix}'), qos_profile=qos_profile_parameters)
                          for suffix, srv in self.SERVICES]
        self._check = node.create_timer(FOREIGN_CLIENT_CHECK_S, self._check_clients,
                                        clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _check_clients(self) -> None:
        """Log one line, once, when a client that cannot be answered (Fast DDS) has matched a parameter service."""
        for service in self._services:
            if service.clients_without_header():
                self._node.get_logger().warning(FOREIGN_CLIENT_TEXT.format(service=service.srv_name))
                self._check.cancel()
                return

    # -- events ----------------------------------------------------------------------------
    def publish_event(self, new=(), changed=()):
        """Publish a ``ParameterEvent`` for parameters just declared (``new``) or changed."""
        if not (new or changed) or self._node._destroyed:
            return
        node = self._node
        cls = _messages.dds_message('rcl_interfaces/msg/ParameterEvent')
        ns = node.get_namespace()
        event = cls(node=(ns + node.get_name()) if ns == '/' else f'{ns}/{node.get_name()}',
                    new_parameters=[_parameter_msg(p) for p in new],
                    changed_parameters=[_parameter_msg(p) for p in changed])
        now = node.get_clock()._now_ns()
        event.stamp.sec, event.stamp.nanosec = divmod(int(now), 1_000_000_000)
        try:
            self._events.publish(event)
        except Exception:   # an event must never break a declaration or a change
            pass

    # -- service callbacks (rclpy.parameter_service) -----------------------------------------
    def _describe_parameters(self, request, response):
        try:
            response.descriptors = [_descriptor_msg(self._node.describe_parameter(n)) for n in request.names]
        except ParameterNotDeclaredException:
            response.descriptors = []
        return response

    def _get_parameters(self, request, response):
        values = []
        for name in request.names:
            try:
                param = self._node.get_parameter(name)
            except (ParameterNotDeclaredException, ParameterUninitializedException):
                response.values = []
                return response
            values.append(value_message(param.value, param.type_))
        response.values = values
        return response

    def _get_parameter_types(self, request, response):
        types = []
        for name in request.names:
            if not self._node.has_parameter(name):
                response.types = []
                return response
            types.append(int(self._node.get_parameter_or(name).type_))
        response.types = types
        return response

    def _list_parameters(self, request, response):
        result = response.result
        prefixes, depth = list(request.prefixes), int(request.depth)
        for name in self._node._parameters:
            if _listed(name, prefixes, depth):
                result.names.append(name)
                prefix = name.rpartition('.')[0]
                if prefix and prefix not in result.prefixes:
                    result.prefixes.append(prefix)
        return response

    def _set(self, parameters):
        """``set_parameters_atomically`` of the node on the request's parameters, as a result."""
        try:
            params = [Parameter(p.name, value=parameter_value(p.value)) for p in parameters]
        except (TypeError, ValueError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        try:
            return self._node.set_parameters_atomically(params)
        except ParameterNotDeclaredException as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        except (InvalidParameterTypeException, InvalidParameterValueException) as exc:
            return SetParametersResult(successful=False, reason=str(exc))

    def _set_parameters(self, request, response):
        response.results = [_result_msg(self._set([p])) for p in request.parameters]
        return response

    def _set_parameters_atomically(self, request, response):
        response.result = _result_msg(self._set(list(request.parameters)))
        return response


class ServiceClient:
    """A blocking service client with rmw_cyclonedds' wire conventions.

    Used by ``uh param`` and the tests; any ROS 2 service server answers it. ``call(request)`` writes the
    request with a header of this client's id and a sequence number and waits for the reply that echoes both.

    Parameters
    ----------
    context : Context
        An initialised context of this backend (its participant is used).
    srv_type : str
        ``'pkg/srv/Name'`` (one of :data:`uh_runtime.messages.SERVICE_DEFINITIONS`).
    srv_name : str
        Fully qualified service name, e.g. ``/uh1/controller/list_parameters``.
    qos_profile : QoSProfile, optional
        Of the request writer and the reply reader; default ``qos_profile_parameters``.
    """

    def __init__(self, context, srv_type: str, srv_name: str, qos_profile=None):
        import random

        from cyclonedds.pub import DataWriter
        from cyclonedds.sub import DataReader
        self.srv_name = srv_name
        request, reply = _endpoints(context, srv_type, srv_name, qos_profile or qos_profile_parameters, 'clientid')
        self._request_cls, self._response_cls = request[1], reply[1]
        self._writer = DataWriter(*request[0])
        self._reader = DataReader(*reply[0])
        self._guid = random.getrandbits(63)
        self._sequence = 0

    def request(self, **fields):
        """Return a request of this service with ``fields`` set."""
        return self._request_cls(**fields)

    def service_is_ready(self) -> bool:
        """Return True when a server's request reader and reply writer are both matched."""
        return bool(matched_subscriptions(self._writer)) and bool(matched_publications(self._reader))

    def wait_for_service(self, timeout_sec: float) -> bool:
        """Wait at most ``timeout_sec`` wall seconds until a server is matched (:meth:`service_is_ready`).

        Return whether it is; a matched server gets 50 ms more so its reply writer matches this reader too.
        """
        deadline = time.monotonic() + timeout_sec
        while not self.service_is_ready():
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.02)
        time.sleep(0.05)   # let the server's reply writer match our reader too
        return True

    def call(self, request, timeout_sec: float = 5.0):
        """Send ``request`` and return the reply (a response of the service), or raise :class:`TimeoutError`."""
        self._sequence += 1
        request.client_guid, request.sequence_number = self._guid, self._sequence
        self._writer.write(request)
        deadline = time.monotonic() + timeout_sec
        while time.monotonic() < deadline:
            for sample in self._reader.take(N=16):
                if sample.sample_info.valid_data and sample.client_guid == self._guid \
                        and sample.sequence_number == self._sequence:
                    return sample
            time.sleep(0.005)
        raise TimeoutError(f'no reply from {self.srv_name} within {timeout_sec:g} s')

    def destroy(self):
        """Delete the client's request writer and reply reader."""
        self._reader.__del__()
        self._writer.__del__()
