"""Logging on the Cyclone DDS backend: rcutils' console format on stderr.

Mirrors ``rclpy.logging`` (``get_logger``, ``set_logger_level``) and
``rclpy.impl.rcutils_logger.RcutilsLogger``: ``[LEVEL] [<unix time>] [<name>]: message``, with
``once``, ``throttle_duration_sec`` and ``skip_first``; levels per logger name (dotted names
inherit their parent's), set by ``--log-level`` through the context and the nodes. A node's
logger (and its children) also publishes every record it prints on ``/rosout``
(``rcl_interfaces/msg/Log``), like rcl's rosout sink, unless ``--disable-rosout-logs``.
"""
import inspect
import sys
import threading
import time

__all__ = ['RcutilsLogger', 'get_logger', 'set_logger_level']

_SEVERITY = {'DEBUG': 10, 'INFO': 20, 'WARN': 30, 'ERROR': 40, 'FATAL': 50}
_log_levels = {'': 20}
_log_lock = threading.Lock()


class RcutilsLogger:
    """``rclpy.impl.rcutils_logger.RcutilsLogger`` subset: ``[LEVEL] [t] [name]: message`` on stderr.

    ``name`` is the dotted logger name ('' for the root logger).
    """

    def __init__(self, name=''):
        self.name = name
        self._once = set()
        self._last = {}
        #: ``(severity, name, message, stamp_ns, file, function, line)`` -> None: the owning
        #: node's /rosout publisher (None: stderr only)
        self._rosout = None

    def get_child(self, name):
        """Return the logger ``<name>.<child>``, publishing on the same ``/rosout``, as rclpy's ``get_child`` does."""
        child = RcutilsLogger(f'{self.name}.{name}' if self.name else name)
        child._rosout = self._rosout
        return child

    def set_level(self, level):
        """Set this logger's level (a level name or its severity number 10-50), as rclpy's ``set_level`` does."""
        name = level if isinstance(level, str) else {10: 'DEBUG', 20: 'INFO', 30: 'WARN',
                                                      40: 'ERROR', 50: 'FATAL'}[int(level)]
        _log_levels[self.name] = _SEVERITY[name.upper()]

    def get_effective_level(self):
        """Return the severity (10-50) that applies: the logger's own level, else its nearest dotted parent's."""
        name = self.name
        while True:
            if name in _log_levels:
                return _log_levels[name]
            if '.' not in name:
                return _log_levels['']
            name = name.rsplit('.', 1)[0]

    def is_enabled_for(self, severity):
        """Return whether a record of level name ``severity`` would be printed, as rclpy's ``is_enabled_for``."""
        return _SEVERITY[severity] >= self.get_effective_level()

    def log(self, message, severity, *, once=False, throttle_duration_sec=None, skip_first=False, **_):
        """Print ``message`` at level ``severity`` (and publish it on ``/rosout``), as rclpy's ``log`` does.

        ``once``, ``throttle_duration_sec`` (wall seconds) and ``skip_first`` apply per call site; other
        keyword arguments are accepted and ignored. Return whether the record was printed.
        """
        severity = 'WARN' if severity == 'WARNING' else severity
        if not self.is_enabled_for(severity):
            return False
        key = inspect.currentframe().f_back.f_back
        key = (key.f_code, key.f_lineno) if key else None
        if once:
            if key in self._once:
                return False
            self._once.add(key)
        if skip_first and key not in self._last:
            self._last[key] = time.monotonic()
            return False
        if throttle_duration_sec:
            now = time.monotonic()
            if key in self._last and now - self._last[key] < throttle_duration_sec:
                return False
            self._last[key] = now
        stamp_ns = time.time_ns()
        with _log_lock:
            sys.stderr.write(f'[{severity}] [{stamp_ns / 1e9:.9f}] [{self.name}]: {message}\n')
            sys.stderr.flush()
        sink = self._rosout
        if sink is not None:
            caller = inspect.currentframe().f_back.f_back
            code = caller.f_code if caller else None
            sink(_SEVERITY[severity], self.name, str(message), stamp_ns, code.co_filename if code else '',
                 code.co_name if code else '', caller.f_lineno if caller else 0)
        return True

    def debug(self, message, **kw):
        """Log ``message`` at DEBUG (keyword arguments as :meth:`log`); return whether it was printed."""
        return self.log(message, 'DEBUG', **kw)

    def info(self, message, **kw):
        """Log ``message`` at INFO (keyword arguments as :meth:`log`); return whether it was printed."""
        return self.log(message, 'INFO', **kw)

    def warning(self, message, **kw):
        """Log ``message`` at WARN (keyword arguments as :meth:`log`); return whether it was printed."""
        return self.log(message, 'WARN', **kw)

    warn = warning

    def error(self, message, **kw):
        """Log ``message`` at ERROR (keyword arguments as :meth:`log`); return whether it was printed."""
        return self.log(message, 'ERROR', **kw)

    def fatal(self, message, **kw):
        """Log ``message`` at FATAL (keyword arguments as :meth:`log`); return whether it was printed."""
        return self.log(message, 'FATAL', **kw)


def get_logger(name):
    """``rclpy.logging.get_logger``."""
    return RcutilsLogger(name)


def set_logger_level(name, level):
    """Set the level of logger ``name`` as ``rclpy.logging.set_logger_level`` does.

    ``level`` is a level name as ``--log-level`` gives it (``DEBUG``, ``INFO``, ``WARN`` or ``WARNING``,
    ``ERROR``, ``FATAL``).
    """
    _log_levels[name] = _SEVERITY['WARN' if level == 'WARNING' else level]
