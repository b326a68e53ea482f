"""What a controller receives under impairments in a realtime run (docs/runtime.md#impairments-in-real-time).

In lockstep, :class:`~uh_controller_node.impairments.ReceivedStates` is given every state of every
neighbour, step by step, and the rule of :func:`~uh_controller_node.impairments.delivered_step`
picks the one a controller uses. In real time the network delivers what it delivers, when it does:
:class:`RealtimeReceivedStates` keeps each state a neighbour's message brought (:meth:`arrive`,
keyed by the step it was sent at, ``UHState.step``) and, at the controller's current step k (that
of its own state, which its simulator publishes at the clock's tick k), uses the newest sent step
``s`` that

- has arrived over the network, and
- the same rule delivers by step k: ``s + delay + jitter draw <= k``, not lost, sent before the
  sender's dropout (:func:`~uh_controller_node.impairments.newest_delivered`, the very function
  the in-process kernel and lockstep call, with the same ``(seed, receiver, sender, step)`` draws).

So the delay of a scenario is in simulated steps *on top of* the real network's latency; a state the
network brought late is simply a step older when it is used. Noise is added and the position
predicted exactly as in lockstep (:func:`~uh_controller_node.impairments.add_noise`,
:func:`~uh_controller_node.impairments.predict_state` over
:func:`~uh_controller_node.impairments.prediction_age`); the age predicted over is the actual one,
``k - s``, network latency included. Nothing here draws a random number.
"""
from __future__ import annotations

import numpy as np

from uh_controller_node.impairments import Link, ReceivedStates, add_noise, compile_impairment_kernels, newest_delivered
from uh_core.layout import STATE_SIZE
from uh_core.reference import VirtualLeaderReference

__all__ = ['newest_arrived', 'RealtimeReceivedStates', 'received_states_for']


def newest_arrived(k: int, arrived, link: Link) -> int | None:
    """Return the newest step of ``arrived`` that the impairment rule delivers by step ``k``, or None.

    Parameters
    ----------
    k : int
        The receiver's current step.
    arrived : collection of int
        Steps (>= 0) whose state of the sender has come over the network (not empty).
    link : Link
        The link's impairment (:class:`~uh_controller_node.impairments.Link`).

    :func:`~uh_controller_node.impairments.newest_delivered` gives the newest step at most a bound
    that the rule delivers by step k; a step the network has not brought yet is skipped by asking
    again below it. None: no arrived state is delivered by k (the initial state has not arrived).
    """
    oldest = min(arrived)
    s = newest_delivered(k, max(arrived), *link)
    while s not in arrived:
        if s <= oldest:
            return None
        s = newest_delivered(k, s - 1, *link)
    return s


class RealtimeReceivedStates(ReceivedStates):
    """The states one controller receives in a realtime run; see the module docstring.

    Same parameters and attributes as :class:`~uh_controller_node.impairments.ReceivedStates`
    (:attr:`history` is here ``{neighbour: {sent step: state}}`` of the states arrived and not yet
    superseded). :meth:`arrive` takes every valid neighbour state as it comes;
    :meth:`receive` is called once per computed step, in step order.
    """

    def arrive(self, j: int, s: int, state) -> None:
        """Keep the state neighbour ``j`` sent at step ``s`` (a copy), unless no step can use it.

        A state sent at or after the sender's dropout is never delivered (that of step 0 always is), nor is one
        older than the state already used (the step used never goes back).
        """
        if (s >= self.drop[j] and s != 0) or s < self.sample_steps.get(j, 0):
            return
        self.history[j][int(s)] = np.array(state, dtype=float)

    def receive(self, k: int, own, neighbours: dict):
        """Return the own state and the states of the neighbours in ``neighbours`` to use at step ``k``.

        ``own`` is the own state of step k; only the keys of ``neighbours`` count (the neighbours the
        synchroniser did not leave out as stale): their states come from those that arrived. Returns
        ``(own, {j: state})`` like :meth:`ReceivedStates.receive`, and sets :attr:`sample_steps` and
        :attr:`delivered` alike. A neighbour none of whose arrived states is delivered by step k yet
        (a controller that joined a running team after the states of step 0 had gone) gets its
        oldest arrived state.
        """
        own_out = np.empty(STATE_SIZE)
        add_noise(np.ascontiguousarray(own, dtype=float), self.sigma, self.seed, self.uh_id, self.uh_id, k, own_out)
        out, self.delivered = {}, {}
        for j in self.neighbours:
            history = self.history[j]
            if j not in neighbours or not history:
                continue
            link = self.link(j)
            s = newest_arrived(k, history, link)
            out[j] = self.use(j, k, min(history) if s is None else s, link)
        return own_out, out


def received_states_for(uh_id: int, neighbours, scenario, dt: float, clock_mode: str):
    """Return what receives controller ``uh_id``'s states under the scenario's impairments, or None.

    None without impairments; :class:`~uh_controller_node.impairments.ReceivedStates` in lockstep,
    :class:`RealtimeReceivedStates` in real time. The impairment kernels are compiled (or loaded
    from numba's cache) here, before the node's endpoints exist.
    """
    if scenario.impairments is None:
        return None
    kind = ReceivedStates if clock_mode == 'lockstep' else RealtimeReceivedStates
    received = kind(uh_id, neighbours, scenario.impairments, dt, VirtualLeaderReference(scenario.reference))
    compile_impairment_kernels()
    return received
