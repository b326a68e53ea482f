"""Intra-process delivery for the Cyclone DDS backend (the counterpart of rclcpp's intra-process comms).

When several nodes share a process (``run_formation.sh --processes per-uh|single``, ROS 2
composition), a message published by one of them reaches the subscriptions of the others in the
same process directly: the subscription gets the published message object itself (and a raw
subscription, e.g. the recorder's, the CDR bytes the publisher serialised once), with no DDS
take and no deserialisation. DDS still carries every message to readers in other processes: each
writer and reader of this backend has Cyclone's ``IgnoreLocal(Participant)`` QoS, so DDS never
matches endpoints of the same process (there is one participant per process) and nothing is
delivered twice. What the ROS graph shows (endpoints, QoS, type hashes) is unchanged.

The semantics follow a DDS match between the two endpoints:

* a publisher feeds a subscription of the same topic when their QoS would match (a reliable
  subscription needs a reliable publisher, a transient-local one a transient-local publisher);
* a keep-last subscription keeps at most ``depth`` undelivered messages (the oldest is dropped);
* a transient-local publisher keeps its last ``depth`` messages and hands them to a compatible
  transient-local subscription created later (late joiners get the history, as from a DDS writer).

As with rclcpp's intra-process comms, a published message object must not be modified afterwards:
the subscriptions of the process receive that object (every message this project publishes is
built fresh for the call). ``UH_INTRA_PROCESS=0`` in the environment turns this off (every
message then goes through DDS, local readers included), e.g. to measure what it saves.
"""
from __future__ import annotations

import collections
import os
import threading

from .qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy

__all__ = ['enabled', 'IntraProcess', 'compatible']


def enabled() -> bool:
    """Whether intra-process delivery is on (default; ``UH_INTRA_PROCESS=0`` turns it off)."""
    return os.environ.get('UH_INTRA_PROCESS', '1').strip().lower() not in ('0', 'false', 'no', 'off')


def compatible(writer_qos, reader_qos) -> bool:
    """Return True when a DDS writer with ``writer_qos`` would match a reader with ``reader_qos``.

    Only reliability and durability are compared, the policies this project varies.
    """
    if reader_qos.reliability == ReliabilityPolicy.RELIABLE and \
            writer_qos.reliability != ReliabilityPolicy.RELIABLE:
        return False
    if reader_qos.durability == DurabilityPolicy.TRANSIENT_LOCAL and \
            writer_qos.durability != DurabilityPolicy.TRANSIENT_LOCAL:
        return False
    return True


def _bound(qos):
    """Queue bound of a keep-last endpoint (None: keep all)."""
    if qos.history == HistoryPolicy.KEEP_ALL:
        return None
    return max(1, int(qos.depth))


class Inbox:
    """Messages delivered in process to one subscription and not yet taken.

    Each item is ``(message or None, CDR bytes or None)``; the subscription turns it into what its
    callback expects (:meth:`take`). The subscription's QoS profile ``qos`` bounds it as a DDS
    reader's history: keep-last ``depth`` (at least 1) drops the oldest, keep-all nothing.
    """

    __slots__ = ('items', 'queued')

    def __init__(self, qos):
        self.items = collections.deque(maxlen=_bound(qos))
        self.queued = False      # listed in IntraProcess.pending

    def take(self, raw: bool, serialize, deserialize) -> list:
        """Every waiting message, as CDR bytes if ``raw`` else as message objects."""
        items = self.items
        out = []
        while items:
            msg, data = items.popleft()
            if raw:
                out.append(data if data is not None else serialize(msg))
            else:
                out.append(msg if msg is not None else deserialize(data))
        return out


class IntraProcess:
    """The in-process links of one context (process): which publisher feeds which subscription.

    Publishers and subscriptions register here when created and leave when destroyed; the
    publisher's :meth:`deliver` puts a message into the inbox of every linked subscription and lists
    that subscription as pending, and the executor takes the pending ones (:meth:`take_pending`).
    ``wake()`` wakes an executor blocked in its wait set (the context's guard condition).
    """

    def __init__(self, wake):
        self._lock = threading.RLock()
        self._wake = wake                      # wakes an executor blocked in its wait set
        self._publishers = collections.defaultdict(list)      # topic -> publishers
        self._subscriptions = collections.defaultdict(list)   # topic -> subscriptions
        self.pending = []                      # subscriptions with waiting messages
        self.spinning_thread = None            # ident of the thread in Executor.spin_once

    # -- registration ---------------------------------------------------------------------------
    def add_publisher(self, pub) -> None:
        """Register ``pub`` and link it to the QoS-compatible subscriptions of its topic in this process."""
        with self._lock:
            self._publishers[pub.topic_name].append(pub)
            pub._local = [s for s in self._subscriptions[pub.topic_name]
                          if compatible(pub.qos_profile, s.qos_profile)]

    def remove_publisher(self, pub) -> None:
        """Unregister ``pub`` and unlink it from every subscription."""
        with self._lock:
            pubs = self._publishers.get(pub.topic_name, [])
            if pub in pubs:
                pubs.remove(pub)
            pub._local = []

    def add_subscription(self, sub) -> None:
        """Register ``sub`` and link it to the QoS-compatible publishers of its topic in this process.

        A transient-local subscription receives the history kept by transient-local publishers at once
        (queued as pending, and the executor woken), as a late-joining DDS reader would.
        """
        with self._lock:
            self._subscriptions[sub.topic_name].append(sub)
            history = False
            for pub in self._publishers[sub.topic_name]:
                if compatible(pub.qos_profile, sub.qos_profile):
                    pub._local = pub._local + [sub]     # a new list: publish() may be iterating
                    if pub._history and sub.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL:
                        sub._inbox.items.extend(pub._history)
                        history = True
            if history:
                self._queue(sub)
        if history:
            self._wake()

    def remove_subscription(self, sub) -> None:
        """Unregister ``sub``, unlink it from every publisher and drop its waiting messages."""
        with self._lock:
            subs = self._subscriptions.get(sub.topic_name, [])
            if sub in subs:
                subs.remove(sub)
            for pub in self._publishers.get(sub.topic_name, []):
                if sub in pub._local:
                    pub._local = [s for s in pub._local if s is not sub]
            sub._inbox.items.clear()

    def local_publisher_count(self, sub) -> int:
        """Count the publishers of this process that feed ``sub``."""
        with self._lock:
            return sum(1 for p in self._publishers.get(sub.topic_name, []) if sub in p._local)

    # -- delivery -------------------------------------------------------------------------------
    def _queue(self, sub) -> None:
        inbox = sub._inbox
        if not inbox.queued:
            inbox.queued = True
            self.pending.append(sub)

    def deliver(self, subscriptions, item) -> None:
        """Put ``item`` = (message or None, CDR bytes) into the inbox of each of ``subscriptions``."""
        with self._lock:
            for sub in subscriptions:
                sub._inbox.items.append(item)
                self._queue(sub)
        if threading.get_ident() != self.spinning_thread:
            self._wake()   # an executor may be blocked waiting in another thread

    def take_pending(self, wanted) -> list:
        """Remove from the pending list and return the pending subscriptions for which ``wanted(sub)`` holds.

        The others stay pending, e.g. those of nodes another executor spins.
        """
        if not self.pending:
            return []
        with self._lock:
            taken, kept = [], []
            for sub in self.pending:
                (taken if wanted(sub) else kept).append(sub)
            self.pending = kept
            for sub in taken:
                sub._inbox.queued = False
        return taken
