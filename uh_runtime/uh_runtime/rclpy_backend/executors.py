"""A static single-threaded executor for the rclpy backend (docs/runtime.md#executors-on-rclpy).

Jazzy's ``rclpy.executors.SingleThreadedExecutor`` rebuilds its wait set for every wait: it walks
every entity of every node in Python, creates a new rcl wait set (a new DDS waitset under
rmw_cyclonedds, which attaches and detaches every reader and guard condition) and wraps each
callback in a ``Task``. At the team's message rates that costs several hundred microseconds per
received message (docs/runtime.md#executors-on-rclpy).

:class:`StaticSingleThreadedExecutor` is rclpy's counterpart of rclcpp's executor of the same
name: it collects the entities once, keeps one wait set (so rmw_cyclonedds keeps its DDS waitset
attached between waits), and rebuilds both only when an entity or node was added or removed
(rclpy's nodes call :meth:`wake` then). Subscription and timer callbacks that are plain functions
run directly; everything else (services, clients, node guard conditions, waitables such as QoS
event handlers, coroutine callbacks) goes through the base executor's own handler, so it behaves
exactly as with rclpy's executor. ``spin_until_future_complete`` and pending tasks fall back to
the base implementation.

Only imported on the rclpy backend; written against the Jazzy rclpy API (``rclpy.executors``).
"""
import inspect

from rclpy.exceptions import InvalidHandle
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.subscription import Subscription
from rclpy.utilities import timeout_sec_to_nsec
from rclpy.waitable import NumberOfEntities

__all__ = ['StaticSingleThreadedExecutor']


def _no_condition() -> bool:
    return False


def _is_plain(callback) -> bool:
    # not a callable test: the __call__ of a callable object is looked at to see whether it is async
    return not (inspect.iscoroutinefunction(callback)
                or inspect.iscoroutinefunction(getattr(callback, '__call__', None)))  # noqa: B004


class _Collection:
    """The entities of the executor's nodes and the one wait set that waits on them."""

    def __init__(self, executor):
        nodes = executor.get_nodes()
        self.subscriptions = [(sub, node, _is_plain(sub.callback)) for node in nodes for sub in node.subscriptions]
        self.timers = [(tmr, node, _is_plain(tmr.callback)) for node in nodes for tmr in node.timers]
        self.services = [(srv, node) for node in nodes for srv in node.services]
        self.clients = [(cli, node) for node in nodes for cli in node.clients]
        self.node_guards = [(gc, node) for node in nodes for gc in node.guards]
        self.waitables = [(wt, node) for node in nodes for wt in node.waitables]
        self.guards = [gc for gc, _ in self.node_guards] + [executor._guard, executor._sigint_gc]
        self.handles = ([executor.context.handle]
                        + [e.handle for e, *_ in self.subscriptions + self.timers + self.services + self.clients]
                        + [gc.handle for gc in self.guards] + [wt for wt, _ in self.waitables])
        count = NumberOfEntities(len(self.subscriptions), len(self.guards), len(self.timers),
                                 len(self.clients), len(self.services))
        for waitable, _ in self.waitables:
            count += waitable.get_num_entities()
        self.wait_set = _rclpy.WaitSet(
            count.num_subscriptions, count.num_guard_conditions, count.num_timers,
            count.num_clients, count.num_services, count.num_events, executor.context.handle)

    def fill(self) -> None:
        """Add every entity again (rcl_wait leaves only the ready ones in the wait set)."""
        ws = self.wait_set
        ws.clear_entities()
        for sub, _, _ in self.subscriptions:
            ws.add_subscription(sub.handle)
        for tmr, _, _ in self.timers:
            ws.add_timer(tmr.handle)
        for srv, _ in self.services:
            ws.add_service(srv.handle)
        for cli, _ in self.clients:
            ws.add_client(cli.handle)
        for gc, _ in self.node_guards:
            if gc._executor_triggered:  # triggered, not yet handled (as rclpy's executor does)
                gc.trigger()
        for gc in self.guards:
            ws.add_guard_condition(gc.handle)
        for waitable, _ in self.waitables:
            waitable.add_to_wait_set(ws)

    def destroy(self) -> None:
        self.wait_set.destroy_when_not_in_use()


class StaticSingleThreadedExecutor(SingleThreadedExecutor):
    """Single-threaded executor that keeps its wait set between waits (see the module doc).

    Constructed as rclpy's executors: ``context`` (default: rclpy's default context).
    """

    def __init__(self, *, context=None) -> None:
        super().__init__(context=context)
        self._collection = None
        self._stale = True

    def wake(self) -> None:
        """Note that an entity or node was added or removed: rebuild the collection before the next wait.

        May be called from any thread; only the spinning thread builds or destroys a collection.
        """
        self._stale = True
        super().wake()

    def add_node(self, node) -> bool:
        """Add ``node`` as rclpy's ``Executor.add_node`` does, and rebuild the collection before the next wait."""
        self._stale = True
        return super().add_node(node)

    def remove_node(self, node) -> None:
        """Remove ``node`` as rclpy's ``Executor.remove_node`` does, and rebuild the collection before the next wait."""
        self._stale = True
        super().remove_node(node)

    def _spin_once_impl(self, timeout_sec=None, wait_condition=_no_condition) -> None:
        if wait_condition is not _no_condition or self._tasks or self._is_shutdown:
            # futures and coroutine tasks: rclpy's own path
            super()._spin_once_impl(timeout_sec, wait_condition)
            return
        self._cb_iter = None  # the base path's leftovers are ready again in our wait set
        if self._stale:   # True from the start, so a collection exists after this
            if self._collection is not None:
                self._collection.destroy()
            self._stale = False
            self._collection = _Collection(self)
        collection = self._collection
        ws = collection.wait_set
        entered = []
        try:
            # in use while waiting, so another thread's destroy() waits for the wait to end
            # (shutdown() destroys the executor's guard conditions), as in rclpy's executor
            for handle in collection.handles:
                handle.__enter__()
                entered.append(handle)
            collection.fill()
            ws.wait(timeout_sec_to_nsec(timeout_sec))
        except InvalidHandle:  # destroyed since the collection was built
            self._stale = True
            return
        finally:
            for handle in entered:
                handle.__exit__(None, None, None)
        if self._is_shutdown:
            return
        if not self._context.ok():
            raise ExternalShutdownException()
        guards_ready = ws.get_ready_entities('guard_condition')
        timers_ready = ws.get_ready_entities('timer')
        subs_ready = ws.get_ready_entities('subscription')
        rare = self._rare_ready(collection, ws, guards_ready)
        for tmr, node, plain in collection.timers:
            try:
                if tmr.handle.pointer not in timers_ready or not tmr.handle.is_timer_ready():
                    continue
            except InvalidHandle:  # destroyed by an earlier callback of this wake-up
                continue
            if plain:
                self._run_timer(tmr)
            else:
                rare.append((tmr, node, self._take_timer))
        for sub, node, plain in collection.subscriptions:
            try:
                if sub.handle.pointer not in subs_ready:
                    continue
            except InvalidHandle:
                continue
            if plain:
                self._run_subscription(sub)
            else:
                rare.append((sub, node, self._take_subscription))
        for entity, node, take in rare:
            handler = self._make_handler(entity, node, take)
            handler()
            with self._tasks_lock:
                self._tasks = [t for t in self._tasks if not t[0].done()]
            handler.result()  # raise the callback's exception, as rclpy's executor does

    @staticmethod
    def _run_timer(tmr) -> None:
        try:
            with tmr.handle:
                tmr.handle.call_timer()
        except InvalidHandle:
            return
        tmr.callback()

    @staticmethod
    def _run_subscription(sub) -> None:
        try:
            with sub.handle:
                msg_info = sub.handle.take_message(sub.msg_type, sub.raw)
        except InvalidHandle:
            return
        if msg_info is None:
            return
        if sub._callback_type is Subscription.CallbackType.MessageOnly:
            sub.callback(msg_info[0])
        else:
            sub.callback(*msg_info)

    def _rare_ready(self, collection, ws, guards_ready) -> list:
        """Ready services, clients, node guard conditions and waitables, for rclpy's handler.

        Collected right after the wait, before any callback runs (a waitable's readiness is
        read from this wait set).
        """
        ready = []
        if collection.services:
            services_ready = ws.get_ready_entities('service')
            ready += [(srv, node, self._take_service) for srv, node in collection.services
                      if srv.handle.pointer in services_ready]
        if collection.clients:
            clients_ready = ws.get_ready_entities('client')
            ready += [(cli, node, self._take_client) for cli, node in collection.clients
                      if cli.handle.pointer in clients_ready]
        for gc, node in collection.node_guards:
            if gc.handle.pointer in guards_ready:
                gc._executor_triggered = True
                ready.append((gc, node, self._take_guard_condition))
        ready += [(wt, node, self._take_waitable) for wt, node in collection.waitables
                  if wt.is_ready(ws)]
        return ready
