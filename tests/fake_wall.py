"""Test doubles for the ROS-free node logic (input synchronisation, clock advancement).

They are a wall clock that moves only when the test says so, and a logger that keeps the lines.
"""


class FakeClock:
    """``now()`` in wall seconds; starts at ``t`` and moves only by :meth:`advance`."""

    def __init__(self, t=100.0):
        self.t = t

    def __call__(self):
        return self.t

    def advance(self, seconds):
        self.t += seconds


class RecordingLogger:
    """Collects ``(level, text)`` of ``info``, ``warning`` and ``error``.

    :meth:`texts` gives the lines of one level (all with ``level=None``).
    """

    def __init__(self):
        self.lines = []

    def info(self, text):
        self.lines.append(('info', text))

    def warning(self, text):
        self.lines.append(('warning', text))

    def error(self, text):
        self.lines.append(('error', text))

    def texts(self, level=None):
        return [text for lvl, text in self.lines if level in (None, lvl)]
