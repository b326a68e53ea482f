"""Test hook of tests/test_recorder_integrity.py: a run's recorder subscribes to one topic late, on purpose.

Python imports ``sitecustomize`` at start-up from ``PYTHONPATH``. In the recorder's process only
(``recorder_node``), with ``UH_TEST_LATE_TOPIC`` set (e.g. ``/uh4/odom``), the recorder's discovery
leaves that topic out for ``UH_TEST_LATE_S`` seconds (default 3) after it first found a publisher of
it, as a slow discovery of one topic would. Every other process is untouched.
"""
import os
import sys

_TOPIC = os.environ.get('UH_TEST_LATE_TOPIC')

if _TOPIC and os.path.basename(sys.argv[0] if sys.argv else '') == 'recorder_node':
    import time

    from uh_runtime.bags import recorder

    _first_seen = []
    _late_s = float(os.environ.get('UH_TEST_LATE_S', '3'))
    _new_topics = recorder.new_topics

    def _late_new_topics(node, followed, wanted=(), skip=()):
        found = _new_topics(node, followed, wanted, skip)
        if any(entry[0] == _TOPIC for entry in found):
            _first_seen[:] = _first_seen or [time.monotonic()]
            if time.monotonic() - _first_seen[0] < _late_s:
                found = [entry for entry in found if entry[0] != _TOPIC]
        return found

    recorder.new_topics = _late_new_topics
