"""The controller core with part of its inputs (a neighbour or the reference stale, docs/graph.md).

The tests cover the remaining-graph check of Assumption 1, the degraded step on a subgraph and the position hold.
"""
import numpy as np
import pytest

from uh_controller_node.controller import ControllerError, UHController
from uh_core.reference import VirtualLeaderReference


class Subgraph:
    """``base`` with the edges into ``uh`` restricted to ``keep``: the graph a degraded step works on.

    Its virtual-leader link is dropped unless ``link``.
    """

    def __init__(self, base, uh, keep, link=True):
        self._base, self._uh, self._keep, self._link = base, uh, tuple(keep), link

    def __getattr__(self, name):
        return getattr(self._base, name)

    def neighbours(self, i):
        return self._keep if i == self._uh else self._base.neighbours(i)

    def leader_link(self, i):
        return self._base.leader_link(i) if (i != self._uh or self._link) else 0.0


def _inputs(paper, k):
    """States of every UH and the reference at step k of a smooth made-up flight (deterministic)."""
    t = k * paper.dt
    ref = VirtualLeaderReference(paper.reference).at(t)
    states = {}
    for i in paper.ids:
        x = np.zeros(12)
        x[0:3] = ref.position + 0.3 * np.array([np.sin(t + i), np.cos(2 * t + i), 0.1 * i])
        x[3:6] = ref.velocity + 0.05 * np.array([np.cos(t + i), -np.sin(t), 0.0])
        x[6:9] = [0.01 * np.sin(t + i), -0.01 * np.cos(t), 0.1 * t + 0.02 * i]
        x[9:12] = [0.001 * i, 0.0, 0.1]
        states[i] = x
    return states, ref


@pytest.mark.parametrize('uh, lost, reachable', [
    (3, {2}, False),     # 3 hears only 2
    (4, {2}, True),      # 4 still hears 1 (linked to the virtual leader)
    (5, {3}, True),      # 5 hears 4, which hears 1
    (1, {3}, True),      # 1 hears the virtual leader
    (1, {0}, False),     # without the reference the leaders' ring 1 <- 3 <- 2 <- 1 has no root
    (2, {0}, False),
    (5, {0}, False),     # followers are reached only through leaders that are reached
    (5, {3, 4}, False),
    (4, {1, 2}, False),  # no leader left that is reached: 3 hears only 2
    (4, {1}, False),     # 1 is the only leader that hears the virtual leader
])
def test_reachability_without_lost_uhs(paper, uh, lost, reachable):
    assert UHController(uh, paper).reachable_without(lost) is reachable


def test_degraded_step_with_every_input_is_the_normal_step(paper):
    """Same inputs, same internal states: bit-identical commands and status (docs/graph.md, docs/control_law.md)."""
    a, b = UHController(1, paper), UHController(1, paper)
    for k in range(50):
        states, ref = _inputs(paper, k)
        nb = {j: states[j] for j in a.neighbours}
        ua, sa = a.step(k, states[1], nb, ref, paper.dt)
        ub, sb = b.step_degraded(k, states[1], nb, ref, paper.dt)
        assert np.array_equal(ua, ub)
        assert np.array_equal(sa.z1, sb.z1) and np.array_equal(sa.fault_estimate_attitude, sb.fault_estimate_attitude)


@pytest.mark.parametrize('uh, stale, link', [(4, 2, True), (5, 3, True), (1, 3, True), (1, 'ref', False)])
def test_degraded_step_is_the_controller_of_the_remaining_graph(paper, uh, stale, link):
    """Leaving out a stale neighbour (or the reference) gives the controller built for the graph without that edge.

    It is exactly that controller: same weights, degree, yaw rule; the internal states carry on.
    """
    keep = tuple(j for j in paper.neighbours(uh) if j != stale)
    degraded = UHController(uh, paper)
    reduced = UHController(uh, Subgraph(paper, uh, keep, link=(stale != 'ref')))
    for k in range(50):
        states, ref = _inputs(paper, k)
        nb = {j: states[j] for j in keep}
        use_ref = ref if (paper.leader_link(uh) > 0 and stale != 'ref') else None
        u1, s1 = degraded.step_degraded(k, states[uh], nb, use_ref, paper.dt)
        u2, s2 = reduced.step(k, states[uh], nb, use_ref, paper.dt)
        assert np.array_equal(u1, u2) and np.array_equal(s1.z1, s2.z1), k


def test_hold_regulates_to_the_held_point(paper):
    ctrl = UHController(3, paper)
    states, ref = _inputs(paper, 0)
    for k in range(10):  # fly normally first: the internal states are not fresh
        states, _ = _inputs(paper, k)
        ctrl.step(k, states[3], {2: states[2]}, None, paper.dt)
    own = states[3]
    hold = (own[0:3] + np.array([0.5, -0.25, 1.0]), 0.3)
    u, status = ctrl.step_degraded(10, own, {}, None, paper.dt, hold=hold)
    # the consensus error is the offset from the held point (degree 1), the yaw target the held yaw
    assert np.allclose(status.z1, own[0:3] - hold[0], atol=1e-12)
    assert status.euler_desired[2] == 0.3
    assert np.all(np.isfinite(u))


def test_degraded_step_errors(paper):
    ctrl = UHController(3, paper)
    states, _ = _inputs(paper, 0)
    with pytest.raises(ControllerError, match=r'unexpected state of UH\(s\) \[4\] that UH 3 does not hear'):
        ctrl.step_degraded(0, states[3], {4: states[4]}, None, paper.dt)
    with pytest.raises(ControllerError, match=r'UH 3 has no neighbour data and no reference to follow; '
                                              r'give hold=\(position, yaw\)'):
        ctrl.step_degraded(0, states[3], {}, None, paper.dt)
    with pytest.raises(ControllerError, match=r'UH 3 hold position must be 3 finite numbers'):
        ctrl.step_degraded(0, states[3], {}, None, paper.dt, hold=([np.nan, 0, 0], 0.0))
