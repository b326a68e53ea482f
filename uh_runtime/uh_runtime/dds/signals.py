"""Signals while blocked in a Cyclone DDS wait: wake-up and SIGTERM (``rclpy.signals``' part).

A thread blocked in a Cyclone wait set does not return to Python when a signal arrives, so the
signal's handler would only run at the next timeout. :func:`wake_on_signals` makes every signal
call ``wake()`` on the registered objects (the DDS backend's contexts and the discovery
:class:`uh_runtime.dds.graph.Graph`), which triggers their guard conditions: the wait returns and Python
runs the handler at once. :func:`shut_down_on_sigterm` handles SIGTERM like rclpy does, by shutting
the contexts down (spinning then raises ``ExternalShutdownException``). :func:`sigint_deferred`
holds Ctrl-C back while Cyclone DDS calls back into Python; :func:`sigint_ignored` ignores it
while a node is torn down.
"""
import contextlib
import os
import signal
import socket
import threading
import weakref

__all__ = ['wake_on_signals', 'shut_down_on_sigterm', 'restore_sigterm', 'sigint_deferred', 'sigint_ignored']

_wakeup_targets = weakref.WeakSet()   # objects with wake(), woken on every signal
_sigterm_contexts = weakref.WeakSet()  # contexts with ok() and _request_shutdown(), shut down on SIGTERM
_wakeup_installed = [False]
_wakeup_sockets = []


def _install_signal_wakeup():
    """Wake every registered target when a signal arrives, so Ctrl-C/SIGTERM act at once.

    The C-level signal handler writes to a socket (``signal.set_wakeup_fd``) even while the main
    thread is blocked inside the Cyclone wait; a daemon thread reading that socket triggers the
    guard conditions, the wait returns and Python runs the signal handler.
    """
    if _wakeup_installed[0] or threading.current_thread() is not threading.main_thread():
        return
    rsock, wsock = socket.socketpair()
    wsock.setblocking(False)
    try:
        signal.set_wakeup_fd(wsock.fileno(), warn_on_full_buffer=False)
    except ValueError:
        return
    _wakeup_installed[0] = True
    _wakeup_sockets.extend((rsock, wsock))  # keep both open for the life of the process

    def pump():
        while True:
            try:
                data = rsock.recv(64)
            except OSError:
                return
            if not data:
                return
            for target in list(_wakeup_targets):
                try:
                    target.wake()
                except Exception:   # noqa: BLE001 -- one target gone (its DDS entities deleted) must
                    pass            # not end this thread: later signals would wake nothing

    threading.Thread(target=pump, name='uh-signal-wakeup', daemon=True).start()


def wake_on_signals(target):
    """Call ``target.wake()`` whenever a signal arrives (main thread only; weakly referenced)."""
    _wakeup_targets.add(target)
    _install_signal_wakeup()


def shut_down_on_sigterm(context):
    """Wake ``context`` on signals and, like rclpy, shut it down on SIGTERM.

    The SIGTERM handler is installed (main thread only) unless SIGTERM already has a handler of
    the application's; :func:`restore_sigterm` removes it once no such context is running.
    """
    _sigterm_contexts.add(context)
    wake_on_signals(context)
    if threading.current_thread() is threading.main_thread() and \
            signal.getsignal(signal.SIGTERM) in (signal.SIG_DFL, None):
        # like rclpy: SIGTERM shuts the contexts down (spin raises ExternalShutdownException)
        signal.signal(signal.SIGTERM, _on_sigterm)


def restore_sigterm():
    """Give SIGTERM back its default action once no context is running."""
    if threading.current_thread() is not threading.main_thread():
        return
    if signal.getsignal(signal.SIGTERM) is _on_sigterm and not any(
            c.ok() for c in list(_sigterm_contexts)):
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _on_sigterm(signum, frame):
    # Runs in the main thread between two bytecodes, possibly inside a callback: only mark the
    # contexts shut down and wake their executors; the DDS entities stay valid until the entry
    # point's ``finally`` destroys the nodes and calls ``try_shutdown`` (nothing is cut off).
    for context in list(_sigterm_contexts):
        context._request_shutdown()


@contextlib.contextmanager
def _sigint_handler(handler):
    """Run the block with ``handler`` for SIGINT and put the previous one back after it.

    Yields the previous handler, or None when nothing was replaced: not the main thread (no Python
    handler runs elsewhere), or a handler not installed from Python (it could not be put back).
    """
    previous = signal.getsignal(signal.SIGINT) if threading.current_thread() is threading.main_thread() else None
    if previous is None:
        yield None
        return
    signal.signal(signal.SIGINT, handler)
    try:
        yield previous
    finally:
        signal.signal(signal.SIGINT, previous)


def sigint_ignored():
    """Ignore SIGINT inside the block (a node's teardown: :func:`uh_runtime.runner.run_node`).

    A second SIGINT must not cut ``destroy_node`` short (the recorder finalises its bag there),
    and a node gets two at once in the ordinary case: ``ros2 launch`` sends SIGINT to its nodes on
    top of the terminal's Ctrl-C, which reaches the whole process group. SIGTERM already only
    marks the context shut down.
    """
    return _sigint_handler(signal.SIG_IGN)


@contextlib.contextmanager
def sigint_deferred():
    """Handle a SIGINT that arrives inside the block only once the block is done.

    A builtin-topic reader's ``take`` calls back into Python from C (cyclonedds builds each
    discovery sample with a Python constructor). A ``KeyboardInterrupt`` raised inside that callback
    is swallowed there and comes out as ``Exception: Callfunc endpoint constructor errored.``: a
    recorder stopped by Ctrl-C while endpoints were disappearing exited with status 1 that way (its
    bag was closed all the same). Deferred, the interrupt is raised right after the take, where the
    node's entry point handles it.
    """
    pending = []
    with _sigint_handler(lambda signum, frame: pending.append(frame)) as previous:
        yield
    if pending:
        if callable(previous):
            previous(signal.SIGINT, pending[0])
        elif previous == signal.SIG_DFL:
            os.kill(os.getpid(), signal.SIGINT)   # the default action, now that it is back
