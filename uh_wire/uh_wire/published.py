"""What a node published, per topic: the ``published:`` line every team node logs when it stops.

The lines of a run's node logs add up to what the bag must hold (tests/test_recorder_integrity.py
checks every topic of a lockstep run's bag against them, docs/testing.md).
"""
from __future__ import annotations

__all__ = ['PublishedCounts']


class PublishedCounts:
    """Messages published per fully qualified topic name, in the order the topics were first counted.

    ``topic_names`` are counted from 0 at once, so the line names them even if nothing is published.
    """

    def __init__(self, *topic_names: str):
        self.counts: dict[str, int] = {name: 0 for name in topic_names}

    def add(self, *topic_names: str) -> None:
        """Count one more message published on each of ``topic_names``."""
        for name in topic_names:
            self.counts[name] = self.counts.get(name, 0) + 1

    def line(self) -> str:
        """Return the log line ``published: /uh1/state 201, /uh1/odom 51, ...`` (every topic counted, zeros too)."""
        return 'published: ' + ', '.join(f'{name} {count}' for name, count in self.counts.items())
