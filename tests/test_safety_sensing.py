"""The safety filter's node path without DDS: sensing, the proximity message, the controller's proximity input.

docs/safety.md#what-the-filter-knows: a plant-side sensing node serves each UH the states of the
others within ``sensing_radius`` (:mod:`uh_sim_node.sensing`), the controller node takes them as an
input of its own (:class:`uh_controller_node.input_sync.InputSynchroniser` with ``sensed``) and
gives them to the filter; the control law never reads them. Wall time is a fake clock; no sleeps.
"""
import math
import subprocess
import sys

import numpy as np
import pytest
from fake_wall import FakeClock, RecordingLogger

from uh_controller_node.controller_diagnostics import ControllerDiagnostics
from uh_controller_node.input_sync import OWN, PROXIMITY, InputSynchroniser, StepInputs
from uh_controller_node.proximity_input import ProximityInput
from uh_controller_node.safety_kernels import PROXIMITY_COLUMNS, proximity_rows
from uh_core import diagnostics as D
from uh_sim_node.clock_node import expected_endpoints
from uh_sim_node.sensing import ProximitySensing, within_radius
from uh_topology.scenario import load_scenario
from uh_wire import topics, wire


def _state(p, v=(0.0, 0.0, 0.0)):
    x = np.zeros(12)
    x[0:3], x[3:6] = p, v
    return x


def test_the_sensing_node_selects_exactly_the_rows_of_the_in_process_kernel():
    # the in-process team loop senses with the compiled kernel, the node with within_radius: the
    # lockstep bag equals the in-process run only if both pick the same rows, also at the boundary
    rng = np.random.default_rng(7)
    out, senders = np.empty((11, PROXIMITY_COLUMNS)), np.empty(11, dtype=np.int64)
    cases = 0
    for _ in range(3000):
        n = int(rng.integers(2, 12))
        positions = rng.uniform(-15.0, 15.0, (n, 3))
        own = int(rng.integers(n))
        if rng.random() < 0.3:     # a UH exactly on the sensing sphere (a distance the radius equals)
            j = (own + 1) % n
            radius = float(np.sqrt(((positions[j] - positions[own]) ** 2).sum()))
        else:
            radius = float(rng.uniform(0.5, 20.0))
        rows = proximity_rows(positions, np.zeros((n, 3)), own, radius, out, senders)
        picked = within_radius(positions, own, radius)
        assert np.array_equal(out[:rows, :3], positions[picked]), (positions, own, radius)
        assert senders[:rows].tolist() == picked
        cases += len(picked)
    assert cases > 1000    # the draws do select UHs


def test_lockstep_serves_every_uh_once_all_states_of_the_step_are_in():
    sensing = ProximitySensing([1, 2, 3], sensing_radius=5.0, lockstep=True, last_step=10)
    assert sensing.offer(2, 0, _state((3.0, 0.0, 0.0))) == []
    assert sensing.offer(1, 0, _state((0.0, 0.0, 0.0))) == []
    assert sensing.offer(3, 1, _state((0.0, 4.0, 0.0))) == []      # step 1 early: held
    reports = sensing.offer(3, 0, _state((0.0, 9.0, 0.0)))
    assert [(r.uh_id, r.step) for r in reports] == [(1, 0), (2, 0), (3, 0)]
    assert reports[0].ids == (2,) and reports[1].ids == (1,) and reports[2].ids == ()   # uh3 is 9 m away
    assert reports[0].steps == (0,)
    assert np.array_equal(reports[0].states[0, :3], [3.0, 0.0, 0.0])
    assert sensing.offer(3, 0, _state((0.0, 1.0, 0.0))) == []      # an old step is ignored
    sensing.offer(1, 1, _state((0.0, 0.0, 0.0)))
    reports = sensing.offer(2, 1, _state((3.0, 0.0, 0.0)))
    assert [r.uh_id for r in reports] == [1, 2, 3] and reports[0].ids == (2, 3)   # uh3 came to 4 m
    assert sensing.offer(1, 11, _state((0.0, 0.0, 0.0))) == []     # beyond the last step


def test_realtime_serves_a_uh_on_its_own_state_and_keeps_a_silent_uh_as_an_obstacle():
    sensing = ProximitySensing([1, 2, 3], sensing_radius=5.0, lockstep=False, last_step=100)
    (first,) = sensing.offer(1, 0, _state((0.0, 0.0, 0.0)))
    assert first.ids == ()                                            # nobody heard yet: nothing reported
    sensing.offer(2, 0, _state((2.0, 0.0, 0.0), (1.0, 0.0, 0.0)))
    for k in range(1, 50):                                            # uh2 falls silent after step 0
        (report,) = sensing.offer(1, k, _state((0.0, 0.0, 0.0)))
        assert report.ids == (2,) and report.steps == (0,)            # kept at its last state, never aged out
    assert np.array_equal(report.states[0, :6], [2.0, 0.0, 0.0, 1.0, 0.0, 0.0])
    assert sensing.offer(1, 10, _state((9.0, 9.0, 9.0))) == []        # older than the state held: ignored
    (report,) = sensing.offer(3, 60, _state((0.0, 3.0, 0.0)))
    assert report.ids == (1, 2) and report.steps == (49, 0)


def test_a_state_of_a_uh_outside_the_team_is_an_error():
    with pytest.raises(ValueError, match='uh9 is not in the team'):
        ProximitySensing([1, 2], 5.0, True, 10).offer(9, 0, _state((0.0, 0.0, 0.0)))


def test_the_proximity_message_carries_the_states_exactly_and_bad_ones_are_rejected():
    sensing = ProximitySensing([1, 2, 3], sensing_radius=12.0, lockstep=True, last_step=10)
    x2 = _state((1.0 / 3.0, 2.0, -0.1), (0.1, -0.2, 0.3))
    x3 = _state((-4.0, 1e-300, 7.0), (5.0, 6.0, 7.0))
    sensing.offer(1, 4, _state((0.0, 0.0, 0.0)))
    sensing.offer(2, 4, x2)
    sensing.next_step = 4
    report = sensing.offer(3, 4, x3)[0]
    msg = wire.proximity_to_msg(report, 0.01, 12.0)
    assert (msg.uh_id, msg.step, msg.sensing_radius) == (1, 4, 12.0)
    assert [s.step for s in msg.states] == [4, 4]
    step, ids, rows = wire.msg_to_proximity(msg, 1)
    assert step == 4 and ids == (2, 3)
    assert np.array_equal(rows, np.stack([x2[:6], x3[:6]]))           # float64 unchanged: bit for bit
    with pytest.raises(wire.WireError, match='expected 2'):
        wire.msg_to_proximity(msg, 2)
    msg.states[1].uh_id = 1
    with pytest.raises(wire.WireError, match='never uh1 itself'):
        wire.msg_to_proximity(msg, 1)
    msg.states[1].uh_id = 2
    with pytest.raises(wire.WireError, match='each other UH at most once'):
        wire.msg_to_proximity(msg, 1)
    msg.states[1].uh_id = 3
    msg.states[1].velocity.y = math.nan
    with pytest.raises(wire.WireError, match='non-finite'):
        wire.msg_to_proximity(msg, 1)


def _sync(mode, **kwargs):
    clock, logger = FakeClock(), RecordingLogger()
    sync = InputSynchroniser(2, (1,), False, mode=mode, dt=0.01, last_step=100, reachable=lambda lost: True,
                             logger=logger, sensed=True, now=clock, sync_wait=2.0 ** -8, startup_grace=1.0,
                             stale_timeout=0.05, **kwargs)
    return sync, clock


def test_lockstep_waits_for_the_proximity_input_of_the_step():
    sync, _ = _sync('lockstep')
    assert sync.offer(OWN, 0, 'own0') == [] and sync.offer(1, 0, 'uh1') == []
    (inputs,) = sync.offer(PROXIMITY, 0, 'prox0')
    assert inputs.proximity == 'prox0' and inputs.neighbours == {1: 'uh1'}
    without, _ = _sync('lockstep')
    without.sensed = False
    with pytest.raises(ValueError, match='does not hear'):
        without.offer(PROXIMITY, 0, 'prox0')


def test_realtime_waits_for_the_proximity_briefly_never_counts_it_stale_and_keeps_the_newest():
    sync, clock = _sync('realtime')
    sync.offer(1, 0, 'uh1')
    assert sync.offer(OWN, 0, 'own0') == []                          # proximity of step 0 not in yet
    (inputs,) = sync.offer(PROXIMITY, 0, 'prox0')                    # ... and now it is: released at once
    assert inputs.proximity == 'prox0' and inputs.stale == ()
    released = []
    for k in range(1, 30):                                           # the sensing node falls silent
        clock.advance(0.01)
        sync.offer(1, k, 'uh1')
        released += sync.offer(OWN, k, f'own{k}')
        clock.advance(2.0 ** -8)
        released += sync.poll()
    assert [r.step for r in released] == list(range(1, 30))
    assert all(r.proximity == 'prox0' and r.stale == () for r in released)   # the newest held, never stale


def test_the_controller_node_gives_the_filter_the_rows_and_names_the_closest_uh():
    class Controller:
        def set_proximity(self, rows):
            self.rows = rows
    controller, held = Controller(), ProximityInput(3, load_scenario('paper').safety and _params(), 0.01)
    assert held.closest(np.zeros(12)) == 0
    rows = np.array([[3.0, 0.0, 0.0, 0, 0, 0], [0.0, 2.0, 0.0, 0, 0, 0], [9.0, 9.0, 9.0, 0, 0, 0]])
    held.use(controller, (0, (4, 5, 7), rows), 0)
    assert controller.rows is rows and held.closest(np.zeros(12)) == 5
    held.use(controller, None, 1)                                    # no new input: the newest is kept
    assert held.closest(_state((8.0, 8.0, 8.0))) == 7


def _params(**changes):
    """Return the filter's parameter vector of the paper scenario with ``changes`` to its safety keys."""
    import dataclasses

    from uh_controller_node.controller import UHController
    scenario = load_scenario('paper')
    scenario = dataclasses.replace(scenario, safety=dataclasses.replace(scenario.safety, **changes))
    return UHController(3, scenario).safety_parameters


def test_controller_diagnostics_say_when_the_filter_acts_and_name_the_closest_uh():
    import types
    diag = ControllerDiagnostics(uh_id=3, every=2, phase=1, safety=True)
    sync = types.SimpleNamespace(lag={}, rejected={})
    status = types.SimpleNamespace(saturated_tilt=False, saturated_collective=False, saturated_cyclic=False,
                                   safety_active=True, closest_distance=1.78,
                                   isolation=types.SimpleNamespace(isolated=(False,) * 4),
                                   fault_estimate_position=np.zeros(3), fault_estimate_attitude=np.zeros(3))
    assert diag.add(0, StepInputs(0, np.zeros(12), {}), status, sync, closest_uh=5) is None
    report = diag.add(1, StepInputs(1, np.zeros(12), {}), status, sync, closest_uh=5)
    assert report.level == D.WARN and 'safety filter active in 2 of 2 step(s)' in report.message
    assert report.values['closest UH'] == 'uh5' and report.values['closest distance (m)'] == '1.780'
    off = ControllerDiagnostics(uh_id=3, every=1, phase=0).add(0, StepInputs(0, np.zeros(12), {}), status, sync)
    assert 'closest UH' not in off.values                            # filter off: nothing about it


def test_with_the_filter_on_the_team_has_a_proximity_topic_per_uh_and_the_sensing_node_hears_every_state():
    on, off = load_scenario('paper', safety=True), load_scenario('paper', safety=False)
    names = {name for name, _ in topics.run_topics(on.ids, **topics.scenario_flags(on))}
    assert {f'/uh{i}/proximity' for i in on.ids} <= names
    assert not any('proximity' in name for name, _ in topics.run_topics(off.ids, **topics.scenario_flags(off)))
    with_filter, without = expected_endpoints(on, recorder=True), expected_endpoints(off, recorder=True)
    for i in on.ids:
        assert with_filter[f'/uh{i}/state'][1] == without[f'/uh{i}/state'][1] + 1      # + the sensing node
        assert with_filter[f'/uh{i}/proximity'] == (1, 2)                              # its controller, recorder


@pytest.mark.parametrize('value, expected', [
    ('off', "runs without the safety filter (safety.enabled: false), so no UH reads a proximity input"),
    ('maybe', "parameter 'safety' is 'maybe'; allowed: on, off, true, false or empty")])
def test_the_sensing_node_started_without_the_filter_or_with_a_bad_setting_says_so_in_one_line(value, expected):
    result = subprocess.run([sys.executable, '-P', '-m', 'uh_sim_node.sensing_node', '--ros-args',
                             '-p', f'safety:={value}'], capture_output=True, text=True, timeout=120)
    assert result.returncode == 2, result.stderr
    assert expected in result.stderr and result.stderr.strip().count('\n') == 0, result.stderr


def test_degraded_sensing_takes_the_newest_report_not_lost_at_least_the_delay_old_and_predicts_it():
    class Controller:
        def set_proximity(self, rows):
            self.rows = rows
    from uh_controller_node.safety_kernels import proximity_lost
    params = _params(proximity_delay_steps=3, proximity_loss=0.4, proximity_seed=5)
    held, controller = ProximityInput(2, params, 0.01), Controller()
    lost = {s for s in range(1, 200) if proximity_lost(params, 2, s)}
    assert 40 < len(lost) < 120 and 0 not in lost and proximity_lost(params, 2, 0) is False   # about 40 %
    for k in range(200):
        rows = np.array([[float(k), 0.0, 0.0, 1.0, 0.0, 0.0]])         # a UH at x = k m moving at 1 m/s
        held.use(controller, (k, (7,), rows), k)
        expected = max((s for s in range(k - 2) if s not in lost), default=None)
        if expected is None:
            assert controller.rows.shape == (0, 6)                     # nothing 3 steps old yet
            continue
        # the report of step s predicted over (k - s) dt with its velocity: x = s + (k - s) 0.01
        assert controller.rows[0, 0] == pytest.approx(expected + (k - expected) * 0.01, abs=1e-12), k
        assert min(held.history) == expected                          # nothing older than the input is kept


def test_without_degradation_the_input_is_the_report_itself_and_noise_is_keyed_by_the_sent_step():
    class Controller:
        def set_proximity(self, rows):
            self.rows = rows
    rows = np.array([[1.0, 2.0, 3.0, 0.1, 0.2, 0.3]])
    exact, controller = ProximityInput(2, _params(), 0.01), Controller()
    exact.use(controller, (4, (7,), rows), 4)
    assert controller.rows is rows                                      # as received, not even copied
    noisy = ProximityInput(2, _params(proximity_noise_position=0.1, proximity_noise_velocity=0.2), 0.01)
    noisy.use(controller, (4, (7,), rows), 4)
    first = controller.rows.copy()
    again = ProximityInput(2, _params(proximity_noise_position=0.1, proximity_noise_velocity=0.2), 0.01)
    again.use(controller, (4, (7,), rows), 4)
    assert np.array_equal(controller.rows, first) and not np.array_equal(first, rows)   # pure function of the keys
    assert np.array_equal(rows, [[1.0, 2.0, 3.0, 0.1, 0.2, 0.3]])      # the report itself is left as it came
