"""The controller node's input synchronisation without ROS (uh_controller_node.input_sync).

The tests cover (docs/reliability.md section 2) lockstep step assembly, realtime sync wait and latest values, staleness,
start-up grace, the position hold when the remaining graph breaks Assumption 1, the join of a restarted controller,
rejection counting and its rate limit, lag statistics.

Deterministic: wall time comes from a fake clock, log lines go to a list; no sleeps, no DDS. The
graph is the paper's (uh3 hears only uh2; uh4 hears uh1, uh2, uh5; uh1 hears uh3 and the virtual
leader).
"""
import numpy as np
import pytest
from fake_wall import FakeClock, RecordingLogger

from uh_controller_node.input_sync import OWN, REFERENCE, InputSynchroniser, input_label
from uh_topology.graph import reachable_from

DT = 0.01
STALE_STEPS = 25          # 0.25 s simulated
SYNC_WAIT = 2.0 ** -8     # wall s (about the default 0.004; a power of two keeps the fake clock exact)
GRACE = 1.0               # wall s


def make(paper, uh, mode='realtime', last_step=6000, **kwargs):
    """Return a synchroniser of UH ``uh`` of the paper graph on a fake clock: (sync, clock, logger)."""
    clock, logger = FakeClock(), RecordingLogger()

    def reachable(lost):
        sources = () if 0 in lost else (0,)
        return uh in reachable_from(paper.adjacency, sources, allowed=set(paper.ids) - set(lost))

    kwargs = {'stale_timeout': STALE_STEPS * DT, 'sync_wait': SYNC_WAIT, 'startup_grace': GRACE, **kwargs}
    sync = InputSynchroniser(uh, paper.neighbours(uh), paper.leader_link(uh) > 0, mode=mode, dt=DT,
                             last_step=last_step, reachable=reachable, logger=logger, now=clock, **kwargs)
    return sync, clock, logger


def state(uh, k):
    """Return a recognisable state: position (uh, k, 10), yaw 0.1 uh."""
    x = np.zeros(12)
    x[0:3] = (uh, k, 10.0)
    x[8] = 0.1 * uh
    return x


def offer_step(sync, uh, k, keys=None):
    """Offer step k of the given inputs (default: every neighbour, then the own state); return everything released."""
    out = []
    for key in (sync.input_keys if keys is None else keys):
        value = ('ref', k) if key == REFERENCE else state(key, k)
        out += sync.offer(key, k, value)
    return out + sync.offer(OWN, k, state(uh, k))


def step_of(value):
    """Step a test value stands for (state row 1, or the reference tuple's second entry)."""
    return value[1] if isinstance(value, tuple) else int(value[1])


# -- lockstep ----------------------------------------------------------------------------------------
def test_lockstep_releases_in_step_order_whatever_the_arrival_order(paper):
    sync, _, _ = make(paper, 4, mode='lockstep')
    assert offer_step(sync, 4, 1) == []            # step 1 complete before step 0: waits for it
    assert sync.offer(1, 0, state(1, 0)) == []
    assert sync.offer(OWN, 0, state(4, 0)) == []
    assert sync.offer(5, 0, state(5, 0)) == []
    released = sync.offer(2, 0, state(2, 0))        # the last input of step 0 releases 0 and 1
    assert [s.step for s in released] == [0, 1]
    for s in released:
        assert step_of(s.own) == s.step and s.own[0] == 4
        assert list(s.neighbours) == [1, 2, 5]
        assert all(step_of(x) == s.step and x[0] == j for j, x in s.neighbours.items())
        assert s.reference is None and s.stale == () and s.hold is None


def test_lockstep_duplicate_replaces_and_old_steps_are_ignored(paper):
    sync, _, _ = make(paper, 3, mode='lockstep')
    first, again = state(3, 0), state(3, 0) + 1.0
    assert sync.offer(OWN, 0, first) == []
    assert sync.offer(OWN, 0, again) == []          # a duplicate before the step completes replaces
    (released,) = sync.offer(2, 0, state(2, 0))
    assert released.own is again
    assert sync.offer(2, 0, state(2, 0)) == []      # step 0 is done: a late copy is ignored ...
    assert sync.offer(OWN, 0, state(3, 0)) == []
    assert sync._pending == {}                      # ... and not kept
    assert [s.step for s in offer_step(sync, 3, 1)] == [1]


def test_lockstep_needs_the_reference_when_linked_and_stops_at_the_last_step(paper):
    sync, _, _ = make(paper, 1, mode='lockstep', last_step=1)
    assert offer_step(sync, 1, 0, keys=[3]) == []   # uh1 hears the virtual leader: needs reference 0
    (released,) = sync.offer(REFERENCE, 0, ('ref', 0))
    assert released.reference == ('ref', 0) and list(released.neighbours) == [3]
    assert [s.step for s in offer_step(sync, 1, 1)] == [1]
    assert offer_step(sync, 1, 2) == []             # beyond the last step


def test_an_input_the_uh_does_not_hear_is_an_error(paper):
    sync, _, _ = make(paper, 3)
    with pytest.raises(ValueError, match='uh3 does not hear uh4'):
        sync.offer(4, 0, state(4, 0))
    with pytest.raises(ValueError, match='uh3 does not hear reference'):
        sync.offer(REFERENCE, 0, ('ref', 0))


# -- realtime: sync wait, latest values ----------------------------------------------------------------
def test_realtime_step_with_every_input_in_is_released_at_once(paper):
    sync, _, _ = make(paper, 4)
    (released,) = offer_step(sync, 4, 0)
    assert released.step == 0 and released.stale == ()
    assert {j: step_of(x) for j, x in released.neighbours.items()} == {1: 0, 2: 0, 5: 0}


def test_realtime_waits_sync_wait_then_uses_the_latest_values(paper):
    sync, clock, _ = make(paper, 4)
    offer_step(sync, 4, 0)
    assert sync.offer(1, 1, state(1, 1)) == []
    assert sync.offer(OWN, 1, state(4, 1)) == []    # uh2 and uh5 of step 1 are not in yet
    clock.advance(SYNC_WAIT / 2)
    assert sync.poll() == []                         # still within the sync wait
    clock.advance(SYNC_WAIT / 2)
    # the wait is over, but only the timer releases a step with data missing (a message handler
    # could be the first of a backlog; see InputSynchroniser.poll)
    assert sync.offer(2, 1, state(2, 1)) == []
    (released,) = sync.poll()
    assert released.step == 1 and released.stale == ()
    assert {j: step_of(x) for j, x in released.neighbours.items()} == {1: 1, 2: 1, 5: 0}
    assert sync.poll() == []                         # released once


def test_realtime_same_step_data_ends_the_wait_early(paper):
    sync, clock, _ = make(paper, 4)
    offer_step(sync, 4, 0)
    assert sync.offer(OWN, 1, state(4, 1)) == []
    assert sync.offer(1, 1, state(1, 1)) == [] and sync.offer(2, 1, state(2, 1)) == []
    (released,) = sync.offer(5, 1, state(5, 1))      # the last input of step 1: no waiting
    assert released.step == 1 and clock.t == 100.0


def test_realtime_ignores_values_older_than_the_one_held(paper):
    sync, clock, _ = make(paper, 4)
    offer_step(sync, 4, 0)
    offer_step(sync, 4, 5)
    assert sync.offer(1, 3, state(1, 3)) == []       # reordered: older than step 5, not taken
    assert sync.offer(OWN, 4, state(4, 4)) == []     # an older own state starts nothing
    assert sync.latest[1][0] == 5 and sync.latest[OWN][0] == 5
    assert offer_step(sync, 4, 6, keys=[2, 5]) == []
    clock.advance(SYNC_WAIT)
    (released,) = sync.poll()
    assert released.step == 6 and step_of(released.neighbours[1]) == 5


def test_realtime_nothing_beyond_the_last_step(paper):
    sync, clock, _ = make(paper, 3, last_step=1)
    assert [s.step for s in offer_step(sync, 3, 0) + offer_step(sync, 3, 1)] == [0, 1]
    assert offer_step(sync, 3, 2) == []
    clock.advance(1.0)
    assert sync.poll() == [] and sync.waiting is None


# -- realtime: staleness, start-up grace, hold --------------------------------------------------------
def run_steps(sync, uh, clock, steps, keys):
    """Offer steps ``steps`` of ``keys`` and the own state, polling after the sync wait each time.

    Returns the released StepInputs.
    """
    out = []
    for k in steps:
        out += offer_step(sync, uh, k, keys=keys)
        clock.advance(SYNC_WAIT)
        out += sync.poll()
    return out


def test_a_neighbour_is_stale_after_the_timeout_and_the_uh_continues_without_it(paper):
    sync, clock, logger = make(paper, 4)
    run_steps(sync, 4, clock, range(0, 11), keys=[1, 2, 5])
    released = run_steps(sync, 4, clock, range(11, 40), keys=[1, 5])   # uh2 falls silent after step 10
    stale = {s.step: s.stale for s in released}
    assert all(stale[k] == () for k in range(11, 11 + STALE_STEPS))    # 10 + 25: at the timeout, fresh
    assert all(stale[k] == (2,) for k in range(11 + STALE_STEPS, 40))
    late = released[-1]
    assert list(late.neighbours) == [1, 5] and late.hold is None and late.stale_labels == ['uh2']
    assert logger.texts('warning') == [
        f'uh2 is stale at step {11 + STALE_STEPS}: newest valid step 10 (timeout 25 steps = 0.25 s)',
        'continuing with uh1, uh5 (the remaining graph satisfies Assumption 1)']
    # a stale input is not waited for: the step is released as soon as the others are in
    assert sync.offer(1, 40, state(1, 40)) == [] and sync.offer(5, 40, state(5, 40)) == []
    (now,) = sync.offer(OWN, 40, state(4, 40))
    assert now.step == 40 and now.stale == (2,)


def test_the_stale_reference_is_named_reference(paper):
    sync, clock, logger = make(paper, 1)
    run_steps(sync, 1, clock, range(0, 2), keys=[3, REFERENCE])
    released = run_steps(sync, 1, clock, range(2, 2 + STALE_STEPS + 2), keys=[3])
    assert released[-1].stale == (REFERENCE,) and released[-1].reference is None
    assert released[-1].stale_labels == ['reference'] and input_label(REFERENCE) == 'reference'
    # without the reference no leader has a path from the virtual leader: uh1 holds
    assert any(t.startswith('without reference, uh1 has no path') for t in logger.texts('warning'))


def test_an_input_never_heard_is_stale_after_the_startup_grace_and_the_uh_holds(paper):
    sync, clock, logger = make(paper, 3)
    assert sync.offer(OWN, 0, state(3, 0)) == []
    for k in range(1, 5):                                  # within the grace: no step without uh2
        clock.advance(GRACE / 5)
        assert sync.offer(OWN, k, state(3, k)) == [] and sync.poll() == []
    clock.advance(GRACE / 2)                               # the grace is over
    (released,) = sync.poll()
    assert released.step == 4 and released.stale == (2,) and released.neighbours == {}
    position, yaw = released.hold
    assert np.array_equal(position, [3.0, 4.0, 10.0]) and yaw == pytest.approx(0.3)
    assert logger.texts('warning') == [
        'uh2 is stale at step 4: never heard (timeout 25 steps = 0.25 s)',
        'without uh2, uh3 has no path from the virtual leader (Assumption 1): holding position '
        '(3.00, 4.00, 10.00) m, yaw 0.300 rad']
    # the hold point stays while uh2 stays away
    (later,) = run_steps(sync, 3, clock, [5], keys=[])
    assert later.hold is released.hold


def test_the_hold_ends_when_the_data_comes_back(paper):
    sync, clock, logger = make(paper, 3)
    run_steps(sync, 3, clock, range(0, 3), keys=[2])
    released = run_steps(sync, 3, clock, range(3, 3 + STALE_STEPS + 5), keys=[])
    assert released[-1].hold is not None
    logger.lines.clear()
    (back,) = run_steps(sync, 3, clock, [40], keys=[2])
    assert back.stale == () and back.hold is None and step_of(back.neighbours[2]) == 40
    assert logger.texts() == ['uh2 is fresh again at step 40',
                              'the graph gives a path from the virtual leader again: following the team']


# -- realtime: restarted controller, own-state silence ------------------------------------------------
def test_a_restarted_controller_skips_the_history_and_joins_at_the_current_step(paper):
    sync, clock, logger = make(paper, 3)
    for k in range(401, 501):                              # transient-local history of uh2 ...
        assert sync.offer(2, k, state(2, k)) == []
    released = []
    for k in range(401, 501):                              # ... and of the own state
        released += sync.offer(OWN, k, state(3, k))
    assert released == []                                  # the first step waits for the backlog to be in
    clock.advance(SYNC_WAIT)
    released = sync.poll()
    assert [s.step for s in released] == [500]             # the newest step, with its neighbours' data
    assert all(step_of(s.neighbours[2]) == 500 for s in released)
    assert logger.texts('info') == ['joining a running team at step 401 or later']
    assert [s.step for s in offer_step(sync, 3, 501)] == [501]   # joined: the next steps as they come
    clock.advance(1.0)
    assert sync.poll() == []


def test_a_restarted_controller_given_the_history_interleaved_computes_no_old_step(paper):
    # the histories of the inputs can come interleaved (each writer's when it is matched): a step
    # whose inputs all came must still not be released before the backlog is in
    sync, clock, _ = make(paper, 3)
    released = []
    for k in range(401, 501):
        released += sync.offer(OWN, k, state(3, k)) + sync.offer(2, k, state(2, k))
    assert released == []
    clock.advance(SYNC_WAIT)
    assert [s.step for s in sync.poll()] == [500]


def test_own_state_silence_is_reported_once(paper):
    sync, clock, logger = make(paper, 3)
    run_steps(sync, 3, clock, range(0, 3), keys=[2])
    clock.advance(0.9)
    assert sync.poll() == [] and logger.texts('warning') == []
    clock.advance(0.2)
    sync.poll()
    sync.poll()
    assert logger.texts('warning') == ['no own state for 1.1 s (newest step 2): is /uh3/sim running? '
                                       'No command is computed until it comes back']
    run_steps(sync, 3, clock, [3], keys=[2])
    assert logger.texts('info') == ['own state arrives again (step 3)']


# -- rejections, lag --------------------------------------------------------------------------------
def test_rejections_are_counted_and_logged_once_a_second_per_input(paper):
    sync, clock, logger = make(paper, 4)
    for _ in range(3):
        sync.reject('state of uh2', 'carries a non-finite value')
        clock.advance(0.25)
    sync.reject('own state', 'carries uh_id 9, expected 4')      # another input: its own rate limit
    clock.advance(0.125)
    sync.reject('state of uh2', 'carries a non-finite value')    # 0.875 s after the report: counted only
    clock.advance(0.125)                                         # 1 s after the report
    sync.reject('state of uh2', 'carries a non-finite value')
    assert logger.texts('error') == [
        'rejected state of uh2: carries a non-finite value; keeping the last valid one (1 rejected so far)',
        'rejected own state: carries uh_id 9, expected 4; keeping the last valid one (1 rejected so far)',
        'rejected state of uh2: carries a non-finite value; keeping the last valid one (5 rejected so far)']
    assert sync.rejected == {'state of uh2': 5, 'own state': 1}
    assert sync.rejected_summary() == 'state of uh2 5, own state 1'


def test_lag_statistics(paper):
    sync, clock, _ = make(paper, 4)
    assert sync.lag_summary() == ''
    offer_step(sync, 4, 0)                                      # lags 0
    run_steps(sync, 4, clock, [2], keys=[1, 2])                 # uh5 2 behind
    run_steps(sync, 4, clock, [3], keys=[1, 5])                 # uh2 1 behind
    assert {key: (s.total, s.count, s.worst) for key, s in sync.lag.items()} == {
        1: (0, 3, 0), 2: (1, 3, 1), 5: (2, 3, 2)}
    assert sync.lag_summary() == 'input lag behind the own state (steps, mean/max): uh1 0.00/0, uh2 0.33/1, uh5 0.67/2'
