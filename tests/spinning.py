"""Spinning an executor in tests: until a condition holds (bounded), for a while, or in a thread."""
import contextlib
import threading
import time


def spin_until(executor, condition, bound):
    """Spin until ``condition()`` is true; fail after ``bound`` s (it only bounds a failure)."""
    end = time.monotonic() + bound
    while not condition():
        remaining = end - time.monotonic()
        assert remaining > 0, 'condition not reached'
        executor.spin_once(timeout_sec=min(remaining, 0.2))


def spin_for(executor, seconds):
    """Spin for ``seconds`` s (to let anything that would still arrive arrive)."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=0.05)


@contextlib.contextmanager
def spinning_in_thread(executor, context, bound=10.0):
    """Spin ``executor`` in a daemon thread while the ``with`` block runs.

    This is for a node that must answer while the test calls it; the thread stops at the end (joined within
    ``bound`` s).
    """
    stop = threading.Event()

    def spin():
        while not stop.is_set() and context.ok():
            executor.spin_once(timeout_sec=0.05)
    thread = threading.Thread(target=spin, daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join(timeout=bound)
