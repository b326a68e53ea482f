"""Spinning an executor in tests: until a condition holds (bounded), or for a while."""
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
