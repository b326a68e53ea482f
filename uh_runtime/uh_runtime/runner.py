"""Entry-point helpers shared by both backends: the Jazzy ``main()`` shape and parameter checks."""
import faulthandler
import fnmatch
import os
import sys

from . import facade as rt
from .dds.signals import sigint_ignored

__all__ = ['check_parameter_overrides', 'run_node', 'declared_parameter_names', 'override_names',
           'log_on_exit']

# Parameters every rclpy node declares by itself (not the application's).
_BUILTIN_PARAMETERS = ('use_sim_time', 'start_type_description_service')


def declared_parameter_names(node) -> list:
    """Names of the parameters ``node`` has declared (either backend)."""
    params = getattr(node, '_parameters', None)
    if params is None:
        params = node.get_parameters_by_prefix('')
    return sorted(params)


def override_names(node) -> list:
    """Return the names of every parameter override that applies to ``node``.

    The overrides come from ``-p``, ``--params-file`` and ``parameter_overrides``. Both rclpy's Node and
    the DDS Node keep them in ``_parameter_overrides``.
    """
    return sorted(getattr(node, '_parameter_overrides', {}) or {})


def check_parameter_overrides(node, ignore=()):
    """Raise if an override names a parameter ``node`` never declared.

    Call it at the end of a node's constructor, or let :func:`run_node` call it. ``ignore`` holds
    names or ``fnmatch`` patterns of overrides that may stay undeclared (e.g. keys of a ``/**:``
    file that other nodes read).

    Raises
    ------
    UnknownParameterOverrideError
        Lists the unknown names and every declared parameter.
    """
    from .dds.parameters import UnknownParameterOverrideError
    declared = set(declared_parameter_names(node))
    unknown = [name for name in override_names(node)
               if name not in declared and not any(fnmatch.fnmatchcase(name, pat) for pat in ignore)]
    if unknown:
        shown = sorted(declared - set(_BUILTIN_PARAMETERS)) or sorted(declared)
        raise UnknownParameterOverrideError(node.get_name(), unknown, shown)


#: Allocations between two collections of the youngest generation once a node spins (Python: 700).
#: 40 UHs in one process (``--processes single``, 5 s lockstep, 200 steady steps): 2.60-2.83 s of
#: wall time with 700, 2.01-2.25 s with 10,000 (interleaved); one process per node: no change.
GC_YOUNG_THRESHOLD = 10_000


def _freeze_startup_objects() -> None:
    """Move every object alive after start-up out of the garbage collector's reach (``gc.freeze``).

    Imports, message types, codecs, the scenario and the nodes themselves are hundreds of thousands
    of objects that live as long as the process; left in the collected generations, each full
    collection walks them all and stops the node for tens of milliseconds (measured: 20 ms in a
    composed team process), which a real-time run sees as late commands. After the freeze a
    collection only walks what was allocated since.

    The youngest generation is then collected every :data:`GC_YOUNG_THRESHOLD` allocations
    instead of Python's 700: a step allocates thousands of short-lived message objects, most freed
    by reference counting before a collection would look at them, and the collections walked the
    rest so often that they were 12 % of a 40-UH ``single`` process's CPU (py-spy). Set
    ``UH_GC_FREEZE=0`` to keep Python's defaults for both.
    """
    if os.environ.get('UH_GC_FREEZE', '1').strip() in ('0', 'false', 'no'):
        return
    import gc
    gc.collect()
    gc.freeze()
    gc.set_threshold(GC_YOUNG_THRESHOLD, *gc.get_threshold()[1:])


def _clear_errors():
    """Exception types that are the user's mistake and get a one-line message, no traceback."""
    from .dds import arguments, parameters
    errors = [parameters.ParameterException, arguments.RosArgsError, arguments.InvalidNameError]
    try:
        import rclpy.exceptions as rex
        errors += [rex.ParameterException, rex.InvalidParameterTypeException,
                   rex.InvalidParameterValueException, rex.ParameterNotDeclaredException,
                   rex.ParameterUninitializedException, rex.InvalidTopicNameException,
                   rex.InvalidNodeNameException, rex.InvalidNamespaceException]
    except (ImportError, AttributeError):
        pass
    return tuple(errors)


def log_on_exit(node, message: str) -> None:
    """Log a node's closing summary (from its ``destroy_node``).

    On the DDS backend through the node's logger. On rclpy straight to stderr in the logger's
    format: at shutdown rclpy's signal handler invalidates the context from another thread, and a
    record logged through rcl while that happens cannot reach ``/rosout`` (rcl prints "Failed to
    publish log message to rosout: publisher's context is invalid"); no check of ``rclpy.ok()``
    closes that window.
    """
    logger = node.get_logger()
    if rt.BACKEND != 'rclpy':
        logger.info(message)
        return
    import time
    sys.stderr.write(f'[INFO] [{time.time():.9f}] [{logger.name}]: {message}\n')
    sys.stderr.flush()


#: Set by the run supervisor (uh_bringup.supervisor) to its pid in its nodes' environment.
SUPERVISOR_ENV = 'UH_SUPERVISOR_PID'


def end_with_supervisor() -> None:
    """Make this node process get SIGTERM (a clean shutdown) when the run supervisor that started it dies.

    This holds even when it dies by SIGKILL, so that no node is left running behind it (Linux's
    parent-death signal).

    Only when ``UH_SUPERVISOR_PID`` names this process's parent (a node started by ``ros2 run`` has
    the wrapper as parent; it is left alone).
    """
    wanted = os.environ.get(SUPERVISOR_ENV, '')
    if not wanted.isdigit() or not sys.platform.startswith('linux') or os.getppid() != int(wanted):
        return
    import ctypes
    import signal
    pr_set_pdeathsig = 1
    ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, int(signal.SIGTERM), 0, 0, 0)
    if os.getppid() != int(wanted):   # the supervisor died before the call: end now
        os.kill(os.getpid(), signal.SIGTERM)


#: Exit status of a node stopped by bad input (parameters, --ros-args, configuration files).
USAGE_STATUS = 2


def _prog(args) -> str:
    argv0 = (args or sys.argv or ['node'])[0]
    return os.path.basename(str(argv0)) or 'node'


def run_node(node_factory, args=None, *, until=None, exit_code=None, user_errors=(),
             ignore_overrides=(), executor=None) -> int:
    """Run node(s) with the Jazzy ``main()`` shape and end the process's work cleanly.

    ``init(args)``; build the node(s) with ``node_factory()`` (one node, or a list of nodes then
    spun together by one executor); check the parameter overrides
    (:func:`check_parameter_overrides`); spin until shutdown, or until ``until(node)`` is true
    (checked after every wake-up; ``node`` is the first node); on ``KeyboardInterrupt`` (SIGINT)
    or ``ExternalShutdownException`` (SIGTERM, ``try_shutdown``) leave quietly; ``finally``
    destroy the nodes and ``try_shutdown()``, so a recorder's ``destroy_node`` always runs.

    A user's mistake prints ``<prog>: error: <message>`` on stderr (no traceback) and exits with
    status 2 (:data:`USAGE_STATUS`, bad input, as for every command of the project): bad ``--ros-args``,
    a parameter error (unknown override, wrong type, out of range,
    on either backend), an exception listed in ``user_errors``, and, while the nodes are being
    built, any ``ValueError``, ``LookupError`` or ``OSError`` (bad configuration, missing file).
    Errors raised later in callbacks keep their traceback.

    Returns 0 when the run ended normally and ``exit_code(node)`` (if given) is 0; any other
    status ends the process with ``SystemExit(status)``. Use as
    ``def main(args=None): rt.run_node(MyNode, args)``.
    """
    from . import procstats
    procstats.install_from_env()
    end_with_supervisor()
    if not faulthandler.is_enabled():
        # a crash in native code (Cyclone DDS, numpy) leaves the Python stack in the node's log
        faulthandler.enable()
    clear = _clear_errors() + tuple(user_errors)
    prog = _prog(args)
    try:
        rt.init(args=args)
    except Exception as exc:  # bad --ros-args: rclpy raises RCLError subclasses, we RosArgsError
        print(f'{prog}: error: {exc}', file=sys.stderr)
        raise SystemExit(USAGE_STATUS) from None
    nodes = []
    status = 0
    try:
        try:
            made = node_factory()
            nodes = list(made) if isinstance(made, (list, tuple)) else [made]
            procstats.set_nodes(nodes)
            for node in nodes:
                check_parameter_overrides(node, ignore=ignore_overrides)
        except clear + (ValueError, LookupError, OSError) as exc:
            print(f'{prog}: error: {exc}', file=sys.stderr)
            status = USAGE_STATUS
        else:
            # rclpy's SingleThreadedExecutor rebuilds its wait set on every wait; this one keeps
            # it (docs/runtime.md#executors-on-rclpy)
            executor = executor or rt.StaticSingleThreadedExecutor()
            procstats.mark_spinning()
            _freeze_startup_objects()
            for node in nodes:
                executor.add_node(node)
            while rt.ok() and not (until is not None and until(nodes[0])):
                executor.spin_once()
            if exit_code is not None:
                status = int(exit_code(nodes[0]))
    except (KeyboardInterrupt, rt.ExternalShutdownException):
        if exit_code is not None and nodes:
            status = int(exit_code(nodes[0]))
    except clear as exc:
        print(f'{prog}: error: {exc}', file=sys.stderr)
        status = USAGE_STATUS
    finally:
        with sigint_ignored():   # a second Ctrl-C must not cut the teardown short
            for node in nodes:
                node.destroy_node()
            rt.try_shutdown()
    if status:
        raise SystemExit(status)
    return 0

