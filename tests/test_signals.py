"""Ctrl-C while Cyclone DDS calls back into Python (uh_runtime.dds.signals.sigint_deferred).

A builtin-topic reader's ``take`` builds each discovery sample through a Python callback called from
C, and cyclonedds turns any exception raised in that callback into a plain ``Exception``
('Callfunc endpoint constructor errored.'). A ``KeyboardInterrupt`` landing there made a recorder
stopped by Ctrl-C exit with status 1. The reader below does what cyclonedds does, in Python.
"""
import os
import signal

import pytest

from uh_runtime.dds.graph import Graph
from uh_runtime.dds.signals import sigint_deferred


class _SwallowingReader:
    """A stand-in for a cyclonedds builtin reader, interrupted by Ctrl-C in the middle of take().

    take() runs a Python constructor per sample and turns what it raises into a plain Exception, as cyclonedds' builtin
    readers do; Ctrl-C arrives while the second sample is built.
    """

    def __init__(self):
        self.finished = False

    def take(self, N):
        samples = []
        for i in range(3):
            try:
                if i == 1:
                    os.kill(os.getpid(), signal.SIGINT)
                samples.append(self._construct(i))
            except BaseException:
                raise Exception('Callfunc endpoint constructor errored.') from None
        self.finished = True
        return samples

    @staticmethod
    def _construct(i):
        total = 0
        for _ in range(10_000):   # bytecodes: where Python runs a pending signal handler
            total += 1
        return (i, total)


@pytest.fixture
def default_sigint():
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def test_without_deferral_ctrl_c_in_the_callback_comes_out_as_a_foreign_error(default_sigint):
    reader = _SwallowingReader()
    with pytest.raises(Exception, match='Callfunc endpoint constructor errored') as caught:
        reader.take(N=1000)
    assert not isinstance(caught.value, KeyboardInterrupt) and not reader.finished


def test_the_graph_takes_whole_and_raises_ctrl_c_after(default_sigint):
    reader = _SwallowingReader()
    with pytest.raises(KeyboardInterrupt):
        Graph._take_builtin(reader)
    assert reader.finished   # the take ran to its end; the interrupt came after it
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler   # handler given back


def test_nothing_pending_nothing_raised_and_the_handler_is_given_back():
    seen = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: seen.append(signum))
    try:
        with sigint_deferred():
            pass
        handler = signal.getsignal(signal.SIGINT)
        os.kill(os.getpid(), signal.SIGINT)
        assert seen == [signal.SIGINT] and handler is signal.getsignal(signal.SIGINT)
    finally:
        signal.signal(signal.SIGINT, previous)


def test_a_target_that_fails_to_wake_does_not_stop_later_wake_ups():
    """The wake-up thread calls every registered target on every signal.

    One whose DDS entities are gone (a closed graph of another node) raised there and ended the thread, so later signals
    woke nothing.
    """
    import threading
    import time

    from uh_runtime.dds.signals import wake_on_signals

    class Gone:
        def wake(self):
            raise RuntimeError('guard condition deleted')

    class Counting:
        def __init__(self):
            self.woken = threading.Semaphore(0)

        def wake(self):
            self.woken.release()
    gone, counting = Gone(), Counting()
    wake_on_signals(gone)
    wake_on_signals(counting)
    previous = signal.signal(signal.SIGINT, lambda signum, frame: None)
    try:
        for _ in range(2):
            os.kill(os.getpid(), signal.SIGINT)
            assert counting.woken.acquire(timeout=10), 'the wake-up thread did not wake the target'
            time.sleep(0.05)
    finally:
        signal.signal(signal.SIGINT, previous)
