"""Executors of the Cyclone DDS backend and the module-level spin functions.

Mirrors ``rclpy.executors`` (``Executor``, ``SingleThreadedExecutor``, ``MultiThreadedExecutor``,
``ExternalShutdownException``) and the spin functions of ``rclpy`` (``spin``, ``spin_once``,
``spin_until_future_complete``, ``get_global_executor``). Callbacks run in the thread that spins,
never in DDS listener threads: the executor blocks in a Cyclone ``WaitSet`` on one read condition
per subscription and the context's guard condition (woken for new entities, shutdown and signals);
the wait times out only at the next wall-clock timer deadline. Each wake-up takes every available
sample of a reader in one batch.
"""
import threading
import time

from .context import get_default_context
from .qos import DDS_INFINITY

__all__ = ['Executor', 'SingleThreadedExecutor', 'StaticSingleThreadedExecutor',
           'MultiThreadedExecutor', 'ExternalShutdownException', 'get_global_executor', 'spin',
           'spin_once', 'spin_until_future_complete']


class ExternalShutdownException(Exception):
    """The context was shut down (``try_shutdown``, SIGTERM) while spinning."""


class _WaitSetCalls:
    """``dds_waitset_attach/detach/wait`` with integer attach arguments (ctypes, loaded once).

    cyclonedds' ``WaitSet.wait`` only returns how many entities triggered; calling
    ``dds_waitset_wait`` with an array gets the attach argument of each triggered entity, so the
    executor visits exactly the ready subscriptions (no ``is_triggered`` call per subscription).
    """

    _loaded = None

    @classmethod
    def get(cls):
        if cls._loaded is None:
            import ctypes as ct

            from cyclonedds.internal import load_cyclonedds
            dll = load_cyclonedds()
            attach, detach, wait = dll.dds_waitset_attach, dll.dds_waitset_detach, dll.dds_waitset_wait
            attach.argtypes, attach.restype = [ct.c_int32, ct.c_int32, ct.c_ssize_t], ct.c_int32
            detach.argtypes, detach.restype = [ct.c_int32, ct.c_int32], ct.c_int32
            wait.argtypes = [ct.c_int32, ct.POINTER(ct.c_ssize_t), ct.c_size_t, ct.c_int64]
            wait.restype = ct.c_int32
            cls._loaded = (attach, detach, wait, ct.c_ssize_t)
        return cls._loaded


#: attach argument of the context's guard condition in an executor's wait set
_GUARD_ARG = 0


def _wait_for_work(waitset_ref, triggered, timeout_ns) -> int:
    """Block in the wait set (at most ``timeout_ns``) and return the number of ready entities.

    ``triggered`` is filled with the attach arguments of the ready entities. A function of its own so that
    profiles (``UH_PROFILE_DIR``) show the time a node spends idle.
    """
    return _WaitSetCalls.get()[2](waitset_ref, triggered, len(triggered), timeout_ns)


class Executor:
    """Runs the callbacks of one or more nodes in the calling thread (``rclpy.executors.Executor``).

    One Cyclone WaitSet holds a read condition per subscription and the context's guard
    condition; ``spin_once`` blocks until data arrives, the guard is triggered (new entity,
    shutdown, signal) or the next wall-clock timer is due, then takes every available sample of
    every ready subscription (the wait set names them) in one batch each and runs the callbacks,
    in the order of the nodes and of their subscriptions, then the due timers. It spins on
    ``context`` (default: the process's default context).
    """

    def __init__(self, *, context=None):
        self._context = context or get_default_context()
        self._nodes = []
        self._waitset = None
        self._attached = {}      # id(subscription) -> (attach argument, read condition)
        self._by_arg = {}        # attach argument -> subscription
        self._rank = {}          # id(subscription) -> dispatch order
        self._next_arg = _GUARD_ARG + 1
        self._triggered = None   # ctypes array the wait fills with attach arguments
        self._dirty = True
        self._is_shutdown = False
        self._lock = threading.RLock()

    @property
    def context(self):
        """The context whose shutdown ends the spinning, as rclpy's ``Executor.context``."""
        return self._context

    def add_node(self, node) -> bool:
        """Add ``node`` (False if it is already added), as rclpy's ``Executor.add_node`` does."""
        with self._lock:
            if node in self._nodes:
                return False
            self._nodes.append(node)
            node._executors.add(self)
            self._dirty = True
        self._context.wake()
        return True

    def remove_node(self, node):
        """Stop running ``node``'s callbacks, as rclpy's ``Executor.remove_node`` does."""
        with self._lock:
            if node in self._nodes:
                # the read conditions are detached lazily at the next wait, so a node that is
                # added again at once (rt.spin_once in a loop) costs nothing
                self._nodes.remove(node)
                node._executors.discard(self)
                self._dirty = True

    def get_nodes(self):
        """Return the nodes added, as rclpy's ``Executor.get_nodes`` does."""
        return list(self._nodes)

    def _entities_changed(self):
        self._dirty = True
        self._context.wake()

    def _detach(self, sub):
        with self._lock:
            self._detach_key(id(sub))

    def _sync(self):
        from cyclonedds.core import WaitSet
        attach, _, _, c_ssize_t = _WaitSetCalls.get()
        with self._lock:
            if self._waitset is None:
                self._waitset = WaitSet(self._context.participant)
                ret = attach(self._waitset._ref, self._context.guard._ref, _GUARD_ARG)
                if ret < 0:
                    raise RuntimeError(f'cannot attach the guard condition to the wait set (DDS error {ret})')
            wanted = [s for n in self._nodes for s in (*n.subscriptions, *n.services)]
            keys = {id(s) for s in wanted}
            for key in list(self._attached):
                if key not in keys:
                    self._detach_key(key)
            for sub in wanted:
                if id(sub) not in self._attached:
                    arg = self._next_arg
                    self._next_arg += 1
                    ret = attach(self._waitset._ref, sub._condition._ref, arg)
                    if ret < 0:
                        raise RuntimeError(f'cannot attach the read condition of {sub.topic_name} to the '
                                           f'wait set (DDS error {ret})')
                    self._attached[id(sub)] = (arg, sub._condition)
                    self._by_arg[arg] = sub
            self._rank = {id(s): i for i, s in enumerate(wanted)}
            if self._triggered is None or len(self._triggered) < len(self._attached) + 1:
                self._triggered = (c_ssize_t * (len(self._attached) + 9))()
            self._dirty = False

    def _detach_key(self, key):
        entry = self._attached.pop(key, None)
        if entry is None:
            return
        arg, cond = entry
        self._by_arg.pop(arg, None)
        if self._waitset is not None:
            try:
                _WaitSetCalls.get()[1](self._waitset._ref, cond._ref)
            except Exception:
                pass

    def _next_timer_ns(self):
        """Nanoseconds until the next wall-clock timer is due (None: no such timer)."""
        best = None
        for node in self._nodes:
            for timer in node.timers:
                if timer._canceled or timer._is_sim():
                    continue
                wait = timer._next - timer._clock._now_ns()
                best = wait if best is None or wait < best else best
        return best

    def spin_once(self, timeout_sec=None):
        """Wait (at most ``timeout_sec``; ``None`` = until something happens) and run ready work."""
        if not self._context.ok() or self._is_shutdown:
            raise ExternalShutdownException()
        try:
            if self._dirty:
                self._sync()
            timeout = DDS_INFINITY if timeout_sec is None else max(0, int(timeout_sec * 1e9))
            due = self._next_timer_ns()
            if due is not None:
                timeout = max(0, min(timeout, due))
            intra = self._context._intra
            if intra is not None:
                intra.spinning_thread = threading.get_ident()
                if intra.pending:   # messages delivered in process are waiting: just poll DDS
                    timeout = 0
            triggered = self._triggered
            n = _wait_for_work(self._waitset._ref, triggered, timeout)
            if n < 0:
                raise RuntimeError(f'waiting in the wait set failed (DDS error {n})')
            ready = triggered[:min(n, len(triggered))]
            if _GUARD_ARG in ready:
                self._context._guard.take()
        except Exception:
            if not self._context.ok():  # shut down (e.g. SIGTERM) while getting ready to wait
                raise ExternalShutdownException() from None
            raise
        if not self._context.ok():
            raise ExternalShutdownException()
        self._dispatch(ready)

    def _dispatch(self, ready=None):
        """Run the callbacks of the ready subscriptions, then the due timers.

        The ready subscriptions are those whose attach arguments are in ``ready`` (all triggered ones if None),
        run in node/subscription order.
        """
        by_arg = self._by_arg
        attached = self._attached
        if ready is None:
            subs = [s for n in list(self._nodes) for s in (*n.subscriptions, *n.services)
                    if id(s) in attached and s._condition.is_triggered()]
        else:
            subs = [by_arg[a] for a in ready if a in by_arg]
        from_dds = {id(s) for s in subs}
        intra = self._context._intra
        if intra is not None and intra.pending:
            subs += [s for s in intra.take_pending(lambda s: id(s) in attached) if id(s) not in from_dds]
        if len(subs) > 1:
            rank = self._rank
            subs.sort(key=lambda s: rank.get(id(s), 0))
        for sub in subs:
            # destroyed, or its node removed, by an earlier callback of this round
            if id(sub) not in attached or (self._dirty and sub._node not in self._nodes):
                continue
            callback = sub.callback
            for msg in sub._take_messages(id(sub) in from_dds):
                callback(msg)
        for node in list(self._nodes):
            for timer in list(node.timers):
                timer._fire_if_due()

    def spin(self):
        """Run callbacks until the context or the executor is shut down, as rclpy's ``Executor.spin`` does.

        Raise :class:`ExternalShutdownException` when the context was shut down.
        """
        while self._context.ok() and not self._is_shutdown:
            self.spin_once()
        if not self._context.ok():
            raise ExternalShutdownException()

    def spin_until_future_complete(self, future, timeout_sec=None):
        """Run callbacks until ``future`` is done, ``timeout_sec`` (wall seconds) passed or shutdown.

        As rclpy's ``Executor.spin_until_future_complete``; ``None`` waits without limit.
        """
        end = None if timeout_sec is None else time.monotonic() + timeout_sec
        while self._context.ok() and not future.done():
            remaining = None if end is None else end - time.monotonic()
            if remaining is not None and remaining <= 0:
                return
            self.spin_once(timeout_sec=remaining)

    def wake(self):
        """Wake the executors waiting on the context (its guard condition), as rclpy's ``Executor.wake`` does."""
        self._context.wake()

    def shutdown(self, timeout_sec=None) -> bool:
        """Stop spinning and remove every node; return True, as rclpy's ``Executor.shutdown`` does (no timeout here)."""
        self._is_shutdown = True
        self._context.wake()
        with self._lock:
            for node in list(self._nodes):
                self.remove_node(node)
            self._waitset = None
            self._attached.clear()
            self._by_arg.clear()
        return True


class SingleThreadedExecutor(Executor):
    """``rclpy.executors.SingleThreadedExecutor``."""


class StaticSingleThreadedExecutor(SingleThreadedExecutor):
    """The facade's executor for the project's nodes (``uh_runtime.rclpy_backend.executors`` on rclpy).

    This backend's executor already keeps its DDS waitset between waits, so it is the same one.
    """


class MultiThreadedExecutor(Executor):
    """Accepts ``num_threads`` for rclpy compatibility; callbacks run one at a time in the spinning thread.

    ``context`` as :class:`Executor`'s.
    """

    def __init__(self, num_threads=None, *, context=None):
        super().__init__(context=context)
        self.num_threads = num_threads


_global_executor = []


def get_global_executor() -> Executor:
    """Return the process's global :class:`SingleThreadedExecutor` (created on first use), as rclpy does."""
    if not _global_executor:
        _global_executor.append(SingleThreadedExecutor())
    return _global_executor[0]


def spin(node, executor=None):
    """``rclpy.spin``: run ``node``'s callbacks until shutdown."""
    executor = get_global_executor() if executor is None else executor
    try:
        executor.add_node(node)
        while executor.context.ok():
            executor.spin_once()
    finally:
        executor.remove_node(node)


def spin_once(node, *, executor=None, timeout_sec=None):
    """``rclpy.spin_once``: wait at most ``timeout_sec`` and run the ready callbacks."""
    executor = get_global_executor() if executor is None else executor
    try:
        executor.add_node(node)
        executor.spin_once(timeout_sec=timeout_sec)
    finally:
        executor.remove_node(node)


def spin_until_future_complete(node, future, executor=None, timeout_sec=None):
    """``rclpy.spin_until_future_complete``: spin ``node`` until ``future`` is done or ``timeout_sec`` s passed."""
    executor = get_global_executor() if executor is None else executor
    try:
        executor.add_node(node)
        executor.spin_until_future_complete(future, timeout_sec)
    finally:
        executor.remove_node(node)
