"""``Node`` of the Cyclone DDS backend, with rclpy's (Jazzy) semantics for the subset listed in docs/runtime.md.

Names, parameters, publishers/subscriptions/timers, graph queries and sim time; mirrors
``rclpy.node``. ROS topic ``/uh1/state`` is DDS topic ``rt/uh1/state`` with type
``uh_msgs::msg::dds_::UHState_``; readers and writers get the QoS mapping of rmw_cyclonedds (see
:mod:`uh_runtime.dds.qos`) and USER_DATA ``typehash=RIHS01_<hex>;``. Graph queries
(``count_subscribers`` ...) read DDS discovery through :class:`uh_runtime.dds.graph.Graph`; with
``use_sim_time`` the node subscribes to ``/clock`` like rclpy's TimeSource.
"""
import weakref

from .. import messages as _messages
from . import arguments as _args
from . import context as _context
from .clock import ROSClock
from .endpoints import Publisher, Subscription, Timer
from .graph import Graph
from .logger import RcutilsLogger, set_logger_level
from .parameters import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    Parameter,
    ParameterAlreadyDeclaredException,
    ParameterDescriptor,
    ParameterImmutableException,
    ParameterNotDeclaredException,
    ParameterType,
    ParameterUninitializedException,
    SetParametersResult,
    check_value,
)
from .qos import as_profile, qos_profile_clock, qos_profile_rosout_default, to_dds_qos

__all__ = ['Node']

#: rclpy's reason when the pre-set callbacks leave nothing to set.
_EMPTY_AFTER_PRE_SET = ('parameter list cannot be empty, this might be due to pre_set_parameters_callback '
                        'modifying the original parameters list.')


class Node:
    """``rclpy.node.Node`` on Cyclone DDS (the subset listed in docs/runtime.md).

    The constructor takes rclpy's arguments with rclpy's meaning; ``enable_logger_service`` is
    accepted and ignored. Raises :class:`NotInitializedException` when the context is not running.
    """

    def __init__(self, node_name, *, context=None, cli_args=None, namespace=None,
                 use_global_arguments=True, enable_rosout=True, start_parameter_services=True,
                 parameter_overrides=None, allow_undeclared_parameters=False,
                 automatically_declare_parameters_from_overrides=False,
                 enable_logger_service=False):
        self._context = context or _context.get_default_context()
        if not self._context.ok():
            raise _context.NotInitializedException('cannot create node')
        self.publishers = []
        self.subscriptions = []
        self.services = []
        self.timers = []
        self._parameter_services = None
        self._rosout = None
        self._executors = weakref.WeakSet()
        self._destroyed = False

        local = _args.parse_ros_args(['--ros-args', *cli_args] if cli_args and '--ros-args' not in cli_args
                                     else (cli_args or []))
        parsed = _args.ParsedArguments()
        parsed.extend(local)
        if use_global_arguments:
            glob = self._context.arguments
            parsed.remaps += glob.remaps
            parsed.parameters = glob.parameters + parsed.parameters
            for logger, level in glob.log_levels.items():
                parsed.log_levels.setdefault(logger, level)
        self._arguments = parsed

        _args.validate_node_name(node_name)
        name, ns_override = _args.apply_name_remaps(parsed.remaps, node_name)
        self._name = name
        self._namespace = ns_override or _args.normalise_namespace(namespace)
        logger_name = '.'.join([*filter(None, self._namespace.split('/')), self._name])
        self._logger = RcutilsLogger(logger_name)
        for logger, level in local.log_levels.items():
            set_logger_level(logger or logger_name, level)

        # parameters
        self._parameters = {}
        self._descriptors = {}
        self._on_set_callbacks = []
        self._pre_set_callbacks = []
        self._post_set_callbacks = []
        self._allow_undeclared = allow_undeclared_parameters
        fq = self.get_fully_qualified_name()
        overrides = {}
        for pattern, params in parsed.parameters:
            if _args.node_pattern_matches(pattern, fq) or pattern in (name, node_name):
                for pname, value in params.items():
                    overrides[pname] = Parameter(pname, value=value)
        for param in parameter_overrides or []:
            overrides[param.name] = param
        self._parameter_overrides = overrides

        # clock and sim time (rclpy's TimeSource)
        self._clock = ROSClock()
        self._clock_sub = None
        _ = self._context.participant  # create the participant before any entity
        self._context._add_node(self)
        # /rosout and /parameter_events (rclpy creates both before declaring use_sim_time)
        rosout_logs = parsed.rosout_logs and (not use_global_arguments or self._context.arguments.rosout_logs)
        if enable_rosout and rosout_logs:
            # rcl's rosout publisher: in ros_discovery_info, not in ``publishers`` (as in rclpy)
            self._rosout = self.create_publisher(_messages.dds_message('rcl_interfaces/msg/Log'), '/rosout',
                                                 qos_profile_rosout_default)
            self.publishers.remove(self._rosout)
            self._logger._rosout = self._publish_log
        from .services import ParameterServices
        self._parameter_services = ParameterServices(self)
        self.declare_parameter('use_sim_time', False)
        self._apply_use_sim_time(self.get_parameter('use_sim_time').value)
        if automatically_declare_parameters_from_overrides:
            for pname, param in overrides.items():
                if pname not in self._parameters:
                    self.declare_parameter(pname, param.value)
        if start_parameter_services:
            self._parameter_services.start_services()

    # -- names ------------------------------------------------------------------------------
    @property
    def context(self):
        """The :class:`~uh_runtime.dds.context.Context` the node belongs to, as rclpy's ``Node.context``."""
        return self._context

    @property
    def executor(self):
        """The executor the node was added to (the first if several), None if none; as rclpy's ``Node.executor``."""
        return next(iter(self._executors), None)

    def get_name(self) -> str:
        """Return the node's name after remapping, as rclpy's ``Node.get_name`` does."""
        return self._name

    def get_namespace(self) -> str:
        """Return the node's absolute namespace (``/`` when none), as rclpy's ``Node.get_namespace`` does."""
        return self._namespace

    def get_fully_qualified_name(self) -> str:
        """Return ``<namespace>/<name>``, as rclpy's ``Node.get_fully_qualified_name`` does."""
        return f"{self._namespace.rstrip('/')}/{self._name}"

    def get_logger(self):
        """Return the node's logger (named ``<namespace parts>.<name>``), as rclpy's ``Node.get_logger`` does."""
        return self._logger

    def get_clock(self):
        """Return the node's ROS clock (sim time while ``use_sim_time`` is set), as rclpy's ``Node.get_clock`` does."""
        return self._clock

    def resolve_topic_name(self, topic, *, only_expand=False) -> str:
        """Fully qualified ROS name of ``topic`` for this node, after remapping."""
        fq = _args.expand_topic_name(topic, self._name, self._namespace)
        if only_expand:
            return fq
        return _args.remap_topic(self._arguments.remaps, fq, self._name, self._namespace)

    def _changed(self):
        for executor in list(self._executors):
            executor._entities_changed()

    # -- publishers and subscriptions -------------------------------------------------------
    def _check_type(self, msg_type):
        if not hasattr(msg_type, '__ros_typename__'):
            raise TypeError(
                f'{msg_type!r} is not a message class of this backend; use '
                'uh_runtime.messages.get_message("pkg/msg/Type")')

    def _endpoint(self, msg_type, topic, qos_profile):
        """Return what a writer or reader of ``topic`` needs.

        That is the resolved name, profile, the intra-process registry (None when off), the DDS topic and the
        DDS QoS (type hash in USER_DATA; local endpoints ignored when intra-process delivery serves them).
        """
        self._check_type(msg_type)
        profile = as_profile(qos_profile)
        name = self.resolve_topic_name(topic)
        intra = self._context._intra
        dds_qos = to_dds_qos(profile, _context.typehash_user_data(msg_type), ignore_local=intra is not None)
        return name, profile, intra, self._context.topic(_context.ROS_TOPIC_PREFIX + name, msg_type), dds_qos

    def create_publisher(self, msg_type, topic, qos_profile, *, callback_group=None,
                         event_callbacks=None, qos_overriding_options=None, publisher_class=None):
        """Create a publisher of ``msg_type`` on ``topic``, as rclpy does (the keyword-only options are ignored)."""
        from cyclonedds.pub import DataWriter
        name, profile, intra, dds_topic, dds_qos = self._endpoint(msg_type, topic, qos_profile)
        pub = Publisher(self, msg_type, name, profile, DataWriter(self._context._pub, dds_topic, qos=dds_qos))
        self.publishers.append(pub)
        if intra is not None:
            intra.add_publisher(pub)
        self._context.publish_discovery_info()
        return pub

    def create_subscription(self, msg_type, topic, callback, qos_profile, *, callback_group=None,
                            event_callbacks=None, qos_overriding_options=None, raw=False):
        """Create a subscription, as rclpy does; with ``raw`` the callback gets CDR bytes (other options ignored)."""
        from cyclonedds.sub import DataReader
        name, profile, intra, dds_topic, dds_qos = self._endpoint(msg_type, topic, qos_profile)
        reader = DataReader(self._context._sub, dds_topic, qos=dds_qos)
        sub = Subscription(self, msg_type, name, callback, profile, reader, raw=raw)
        self.subscriptions.append(sub)
        if intra is not None:
            intra.add_subscription(sub)
        self._context.publish_discovery_info()
        self._changed()
        return sub

    def create_service(self, srv_type, srv_name, callback, *, qos_profile=None, callback_group=None):
        """Create a service server (:class:`~uh_runtime.dds.services.Service`).

        ``srv_type`` is ``'pkg/srv/Name'``, one of :data:`uh_runtime.messages.SERVICE_DEFINITIONS`.
        """
        from .services import Service, qos_profile_parameters
        service = Service(self, srv_type, srv_name, callback, as_profile(qos_profile or qos_profile_parameters))
        self.services.append(service)
        self._context.publish_discovery_info()
        self._changed()
        return service

    def destroy_service(self, service) -> bool:
        """Destroy ``service`` (False if it is not the node's), as rclpy's ``Node.destroy_service`` does."""
        if service not in self.services:
            return False
        self.services.remove(service)
        self._changed()
        for executor in list(self._executors):
            executor._detach(service)
        service._condition.__del__()
        service._reader.__del__()
        service._writer.__del__()
        self._context.publish_discovery_info()
        return True

    def _publish_log(self, severity: int, name: str, message: str, stamp_ns: int, file: str,
                     function: str, line: int) -> None:
        """Publish one log record on ``/rosout`` (rcl_interfaces/msg/Log), as rcl's rosout sink."""
        pub = self._rosout
        if pub is None or self._destroyed or not self._context.ok():
            return
        msg = pub.msg_type(level=int(severity), name=name, msg=message, file=file, function=function,
                           line=int(line))
        msg.stamp.sec, msg.stamp.nanosec = divmod(int(stamp_ns), 1_000_000_000)
        try:
            pub.publish(msg)
        except Exception:   # logging must never raise
            pass

    def create_timer(self, timer_period_sec, callback, callback_group=None, clock=None,
                     autostart=True):
        """Call ``callback`` every ``timer_period_sec`` s of ``clock`` (default: the node's), as rclpy's timer."""
        timer = Timer(self, callback, int(round(float(timer_period_sec) * 1e9)),
                      clock or self._clock, autostart)
        self.timers.append(timer)
        self._changed()
        return timer

    def destroy_publisher(self, publisher) -> bool:
        """Destroy ``publisher`` (False if it is not the node's), as rclpy's ``Node.destroy_publisher`` does."""
        if publisher not in self.publishers:
            return False
        self.publishers.remove(publisher)
        if self._context._intra is not None:
            self._context._intra.remove_publisher(publisher)
        publisher._writer.__del__()
        self._context.publish_discovery_info()
        return True

    def destroy_subscription(self, subscription) -> bool:
        """Destroy ``subscription`` (False if it is not the node's), as rclpy's ``Node.destroy_subscription`` does."""
        if subscription not in self.subscriptions:
            return False
        self.subscriptions.remove(subscription)
        if self._context._intra is not None:
            self._context._intra.remove_subscription(subscription)
        self._changed()
        for executor in list(self._executors):
            executor._detach(subscription)
        subscription._condition.__del__()
        subscription._reader.__del__()
        self._context.publish_discovery_info()
        return True

    def destroy_timer(self, timer) -> bool:
        """Cancel and remove ``timer`` (False if it is not the node's), as rclpy's ``Node.destroy_timer`` does."""
        if timer not in self.timers:
            return False
        self.timers.remove(timer)
        timer.cancel()
        self._changed()
        return True

    def destroy_node(self):
        """Delete every entity of the node and remove it from ``ros_discovery_info``."""
        if self._destroyed:
            return True
        self._destroyed = True
        for timer in list(self.timers):
            self.destroy_timer(timer)
        self._logger._rosout = None
        rosout, self._rosout = self._rosout, None
        if rosout is not None:
            self.publishers.append(rosout)   # destroyed with the others
        if self._context._dp is not None:
            for service in list(self.services):
                self.destroy_service(service)
            for sub in list(self.subscriptions):
                self.destroy_subscription(sub)
            for pub in list(self.publishers):
                self.destroy_publisher(pub)
        else:
            self.services.clear()
            self.subscriptions.clear()
            self.publishers.clear()
        for executor in list(self._executors):
            executor.remove_node(self)
        self._context._remove_node(self)
        return True

    # -- graph ------------------------------------------------------------------------------
    def _graph(self):
        if getattr(self, '_graph_cache', None) is None:
            self._graph_cache = Graph(
                participant=self._context.participant,
                info_topic=self._context.topic(
                    _context.DISCOVERY_TOPIC,
                    _messages.dds_message('rmw_dds_common/msg/ParticipantEntitiesInfo')))
        self._graph_cache.update()
        return self._graph_cache

    def count_publishers(self, topic_name) -> int:
        """Writers of the topic in the domain (this process's included), from DDS discovery."""
        return self._graph().count(self.resolve_topic_name(topic_name), writers=True)

    def count_subscribers(self, topic_name) -> int:
        """Readers of the topic in the domain (this process's included), from DDS discovery."""
        return self._graph().count(self.resolve_topic_name(topic_name), writers=False)

    def get_publishers_info_by_topic(self, topic_name, no_mangle=False):
        """Return ``rclpy``'s list of endpoint infos of the topic's writers.

        Each has node_name, node_namespace, topic_type, endpoint_type, endpoint_gid, qos_profile.
        """
        name = topic_name if no_mangle else self.resolve_topic_name(topic_name)
        return self._graph().endpoints(name, writers=True)

    def get_subscriptions_info_by_topic(self, topic_name, no_mangle=False):
        """Return ``rclpy``'s list of endpoint infos of the topic's readers, as :meth:`get_publishers_info_by_topic`."""
        name = topic_name if no_mangle else self.resolve_topic_name(topic_name)
        return self._graph().endpoints(name, writers=False)

    def get_topic_names_and_types(self, no_demangle=False):
        """Return sorted ``[(topic name, [type names])]`` of the domain's ROS topics, as rclpy does."""
        return self._graph().topic_names_and_types()

    def get_node_names(self):
        """Return the names of the nodes in the domain (this process's included), as rclpy's ``get_node_names``."""
        return [name for name, _ in self._graph().node_names_and_namespaces()]

    def get_node_names_and_namespaces(self):
        """Return sorted ``(name, namespace)`` of the nodes in the domain (this process's included), as rclpy does."""
        return self._graph().node_names_and_namespaces()

    # -- parameters ------------------------------------------------------------------------
    def declare_parameter(self, name, value=None, descriptor=None, ignore_override=False):
        """Declare one parameter, as rclpy (Jazzy) does.

        ``value`` may be a default value or a ``Parameter.Type`` (statically typed, no default).
        The override from the command line or ``parameter_overrides`` wins over the default unless
        ``ignore_override``; it must have the declared type (or be an int for a double) and pass
        the descriptor's range, else :class:`InvalidParameterTypeException` /
        :class:`InvalidParameterValueException` name the parameter and what is allowed.
        """
        return self.declare_parameters('', [(name, value, descriptor or ParameterDescriptor())],
                                       ignore_override)[0]

    def declare_parameters(self, namespace, parameters, ignore_override=False):
        """Declare ``parameters`` under ``namespace`` as rclpy does; return the declared :class:`Parameter` objects.

        Each entry is a name or ``(name, value[, descriptor])``, declared as ``<namespace>.<name>`` as by
        :meth:`declare_parameter`; one ``/parameter_events`` message announces them.
        """
        declared = []
        for entry in parameters:
            entry = tuple(entry) if isinstance(entry, (tuple, list)) else (entry,)
            name = f'{namespace}.{entry[0]}' if namespace else entry[0]
            value = entry[1] if len(entry) > 1 else None
            descriptor = entry[2] if len(entry) > 2 and entry[2] is not None else ParameterDescriptor()
            if not isinstance(name, str) or not name:
                raise TypeError(f'parameter name must be a non-empty str, got {name!r}')
            if name in self._parameters:
                raise ParameterAlreadyDeclaredException(name)
            if isinstance(value, ParameterType):
                if value == ParameterType.NOT_SET:
                    raise ValueError(
                        f'Cannot declare parameter {{{name}}} as statically typed of type NOT_SET')
                ptype, value = value, None
            elif value is None:
                if not descriptor.dynamic_typing:
                    raise ValueError(
                        f"parameter '{name}': cannot declare a statically typed parameter without "
                        'a default value; give a default, a Parameter.Type, or '
                        'ParameterDescriptor(dynamic_typing=True)')
                ptype = ParameterType.NOT_SET
            else:
                try:
                    ptype = ParameterType.from_parameter_value(value)
                except TypeError as exc:
                    raise TypeError(f"parameter '{name}': {exc}") from None
            descriptor.name = name
            if not descriptor.dynamic_typing:
                descriptor.type = int(ptype)
            if not ignore_override and name in self._parameter_overrides:
                value = self._parameter_overrides[name].value
            value = self._coerce(name, value, descriptor)
            reason = check_value(name, value, descriptor) if value is not None else None
            if reason:
                raise InvalidParameterValueException(name, value, reason)
            param = Parameter(name, value=value)
            result = self._run_set_callbacks([param])
            if not result.successful:
                raise InvalidParameterValueException(name, value, result.reason)
            self._descriptors[name] = descriptor
            self._parameters[name] = param
            self._run_post_callbacks([param])
            declared.append(param)
        if self._parameter_services is not None:
            self._parameter_services.publish_event(new=declared)
        return declared

    def _coerce(self, name, value, descriptor):
        """Type check against a statically typed descriptor.

        As in rclpy, an integer is *not* accepted for a double parameter (``-p rate:=20`` for a
        double fails; write ``20.0``), so a command line that works here works on ROS 2 too.
        """
        if value is None or descriptor.dynamic_typing or not descriptor.type:
            return value
        expected = ParameterType(descriptor.type)
        if not expected.check(value):
            raise InvalidParameterTypeException(name, value, expected)
        return value

    def undeclare_parameter(self, name):
        """Remove parameter ``name`` as rclpy does; raise if it is undeclared or read-only."""
        if name not in self._parameters:
            raise ParameterNotDeclaredException(name, self._parameters)
        if self._descriptors[name].read_only:
            raise ParameterImmutableException(name)
        del self._parameters[name]
        del self._descriptors[name]

    def has_parameter(self, name) -> bool:
        """Return whether parameter ``name`` is declared, as rclpy's ``Node.has_parameter`` does."""
        return name in self._parameters

    def get_parameter(self, name) -> Parameter:
        """Return parameter ``name``, as rclpy's ``Node.get_parameter`` does.

        Raise :class:`ParameterUninitializedException` (statically typed, no value yet) or
        :class:`ParameterNotDeclaredException` (an unset :class:`Parameter` if undeclared ones are allowed).
        """
        if name in self._parameters:
            param = self._parameters[name]
            if param.type_ == ParameterType.NOT_SET and self._descriptors[name].type and \
                    not self._descriptors[name].dynamic_typing:
                raise ParameterUninitializedException(name)
            return param
        if self._allow_undeclared:
            return Parameter(name)
        raise ParameterNotDeclaredException(name, self._parameters)

    def get_parameters(self, names):
        """Return the parameters ``names`` (:meth:`get_parameter` each), as rclpy's ``Node.get_parameters`` does."""
        return [self.get_parameter(n) for n in names]

    def get_parameter_or(self, name, alternative_value=None):
        """Return parameter ``name``, or ``alternative_value`` (an unset :class:`Parameter` if None) if undeclared."""
        if name not in self._parameters:
            return Parameter(name, value=None) if alternative_value is None else alternative_value
        return self._parameters[name]

    def get_parameters_by_prefix(self, prefix):
        """Return ``{name without '<prefix>.': Parameter}`` of the parameters under ``prefix`` ('': all), as rclpy."""
        prefix = prefix + '.' if prefix else ''
        return {n[len(prefix):]: p for n, p in self._parameters.items() if n.startswith(prefix)}

    def describe_parameter(self, name):
        """Return the descriptor of ``name`` as rclpy does (:class:`ParameterNotDeclaredException` if undeclared)."""
        if name not in self._descriptors:
            raise ParameterNotDeclaredException(name, self._parameters)
        return self._descriptors[name]

    def describe_parameters(self, names):
        """Return the descriptors of the parameters ``names``, as rclpy's ``Node.describe_parameters`` does."""
        return [self.describe_parameter(n) for n in names]

    def set_parameters(self, parameter_list):
        """Set each parameter on its own (one :class:`SetParametersResult` each), as rclpy's ``Node.set_parameters``."""
        return [self.set_parameters_atomically([p]) for p in parameter_list]

    def set_parameters_atomically(self, parameter_list):
        """Set ``parameter_list`` all or none, as rclpy's ``Node.set_parameters_atomically`` does.

        The pre-set callbacks may first change the list (:meth:`add_pre_set_parameters_callback`); types,
        descriptors and on-set callbacks must accept every value (the result names the first refusal); then
        the values are stored and announced and the post-set callbacks run.
        """
        if self._pre_set_callbacks:
            parameter_list = [param for callback in self._pre_set_callbacks for param in callback(parameter_list)]
            if not parameter_list:
                return SetParametersResult(successful=False, reason=_EMPTY_AFTER_PRE_SET)
        for param in parameter_list:
            if param.name not in self._parameters:
                if not self._allow_undeclared:
                    raise ParameterNotDeclaredException(param.name, self._parameters)
        checked = []
        for param in parameter_list:
            desc = self._descriptors.get(param.name, ParameterDescriptor(dynamic_typing=True))
            if desc.read_only:
                return SetParametersResult(successful=False,
                                           reason=f"parameter '{param.name}' is read-only")
            try:
                value = self._coerce(param.name, param.value, desc)
            except InvalidParameterTypeException as exc:
                return SetParametersResult(successful=False, reason=str(exc))
            reason = check_value(param.name, value, desc) if value is not None else None
            if reason:
                return SetParametersResult(successful=False, reason=f"parameter '{param.name}': {reason}")
            checked.append(Parameter(param.name, value=value))
        result = self._run_set_callbacks(checked)
        if result.successful:
            new = [p for p in checked if p.name not in self._parameters]
            for param in checked:
                self._parameters[param.name] = param
                self._descriptors.setdefault(param.name, ParameterDescriptor(name=param.name))
            if self._parameter_services is not None:
                self._parameter_services.publish_event(new=new, changed=[p for p in checked if p not in new])
            self._run_post_callbacks(checked)
        return result

    def add_on_set_parameters_callback(self, callback):
        """Register ``callback(params) -> SetParametersResult`` ahead of the others; a refusal stops the set (rclpy)."""
        self._on_set_callbacks.insert(0, callback)

    def remove_on_set_parameters_callback(self, callback):
        """Unregister an on-set callback, as rclpy's ``Node.remove_on_set_parameters_callback`` does."""
        self._on_set_callbacks.remove(callback)

    def add_pre_set_parameters_callback(self, callback):
        """Register ``callback(params) -> params`` ahead of the others, as rclpy does.

        Before parameters are set (not declared), each callback gets the list being set and returns parameters;
        the lists they return, joined, are set instead (atomically). An empty list is an unsuccessful set.
        """
        self._pre_set_callbacks.insert(0, callback)

    def add_post_set_parameters_callback(self, callback):
        """Register ``callback(parameters)``, called after parameters are declared or set, as rclpy does."""
        self._post_set_callbacks.insert(0, callback)

    def _run_set_callbacks(self, params):
        for callback in self._on_set_callbacks:
            result = callback(params)
            if not result.successful:
                return result
        return SetParametersResult(successful=True)

    def _run_post_callbacks(self, params):
        for param in params:
            if param.name == 'use_sim_time' and hasattr(self, '_clock'):
                self._apply_use_sim_time(param.value)
        for callback in self._post_set_callbacks:
            callback(params)

    # -- sim time --------------------------------------------------------------------------
    def _apply_use_sim_time(self, enabled):
        enabled = bool(enabled)
        if enabled and self._clock_sub is None:
            clock_cls = _messages.dds_message('rosgraph_msgs/msg/Clock')
            self._clock_sub = self.create_subscription(
                clock_cls, '/clock', self._on_clock, qos_profile_clock)
            self._clock._set_ros_time_is_active(True)
        elif not enabled and self._clock_sub is not None:
            self.destroy_subscription(self._clock_sub)
            self._clock_sub = None
            self._clock._set_ros_time_is_active(False)

    def _on_clock(self, msg):
        now = msg.clock.sec * 1_000_000_000 + msg.clock.nanosec
        if now < self._clock._override_ns:
            for timer in self.timers:
                timer._sim_jump(now)
        self._clock._set_ros_time(now)
