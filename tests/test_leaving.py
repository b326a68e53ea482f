"""A stuck actuator and a UH that leaves the team (docs/resilience.md#leaving-the-team, docs/faults.md)."""
import numpy as np
import pytest
from scenario_texts import paper_yaml

from uh_controller_node.fault_isolation import FaultIsolator
from uh_controller_node.isolation_runs import first_unable
from uh_controller_node.loss_tracker import LossTracker
from uh_sim_node.faults import FaultError, inject
from uh_sim_node.helicopter import plant_from_scenario
from uh_team.separation_metrics import closest_pair_series
from uh_team.team_events import NEVER, loss_schedule
from uh_team.team_simulation import run_team_simulation
from uh_topology import errors as E
from uh_topology.scenario import load_scenario, parse_scenario

STUCK_STEP = 2500     # t = 25 s at dt = 0.01 s
LATERAL = 2


def stuck(uh: int, channel: str, extra: str = 'resilience: {}\n', time: float = 25.0):
    """Give the paper scenario with UH ``uh``'s ``channel`` stuck at ``time`` and ``extra`` keys."""
    return parse_scenario(paper_yaml(f'events:\n  - {{time: {time}, uh: {uh}, kind: stuck, channel: {channel}}}\n'
                                     f'{extra}'), source='stuck.yaml')


@pytest.fixture(scope='module')
def lateral_run():
    """UH1 (the leader hearing the virtual leader) with its lateral cyclic stuck at 25 s; the team answers."""
    scenario = stuck(1, 'lateral')
    return scenario, run_team_simulation(scenario, 'proposed')


@pytest.fixture(scope='module')
def lateral_run_staying():
    """Fly the same with ``on_unable: stay``: the UH flies on with its stuck actuator, as without this layer."""
    scenario = stuck(1, 'lateral', 'resilience: {on_unable: stay}\n')
    return scenario, run_team_simulation(scenario, 'proposed')


# -- bad input -----------------------------------------------------------------------------------------------
@pytest.mark.parametrize('text, error, where', [
    ('events:\n  - {time: 3.0, uh: 2, kind: stuck}\n', E.MissingFieldError, 'events[0]'),
    ('events:\n  - {time: 3.0, uh: 2, kind: stuck, channel: rudder}\n', E.InvalidValueError, 'events[0].channel'),
    ('events:\n  - {time: 3.0, uh: 2, kind: stuck, channel: 4}\n', E.InvalidValueError, 'events[0].channel'),
    ('events:\n  - {time: 3.0, uh: 2, kind: lost, channel: 1}\n', E.InvalidValueError, 'events[0].channel'),
    ('events:\n  - {time: 3.0, uh: 2, kind: stuck, channel: 1}\n  - {time: 4.0, uh: 2, kind: lost}\n',
     E.InvalidValueError, 'events[1].uh'),
    ('resilience: {on_unable: pray}\n', E.InvalidValueError, 'resilience.on_unable'),
    ('resilience: {unable_rho: 1.0}\n', E.InvalidValueError, 'resilience.unable_rho'),
    ('resilience: {leave_climb: -1.0}\n', E.InvalidValueError, 'resilience.leave_climb'),
])
def test_bad_stuck_events_are_one_line_naming_file_line_and_key(text, error, where):
    with pytest.raises(error) as info:
        parse_scenario(paper_yaml(text), source='bad.yaml')
    message = str(info.value)
    assert '\n' not in message and message.startswith('bad.yaml:') and where in message, message


def test_a_stuck_event_reads_its_channel_by_any_name():
    for name in ('lateral', 'delta_lat', 2):
        (event,) = stuck(3, name).events
        assert (event.kind, event.uh, event.channel, event.step) == ('stuck', 3, LATERAL, STUCK_STEP)


# -- the plant: the actuator stays where it is ---------------------------------------------------------------
def test_a_stuck_actuator_stays_where_the_command_before_left_it_whatever_is_commanded():
    scenario = load_scenario('paper')
    plant = plant_from_scenario(scenario, 2)      # UH2's lateral has rho 0.85 and a bias from 10 s
    u_before = np.array([0.1, 0.05, 0.02, -0.01])
    expected = plant.actual_inputs(u_before, 20.0)[LATERAL]     # 0.85 * 0.02 + 0.005
    fault = plant.stick(LATERAL, u_before, 20.0)
    assert (fault.rho, fault.bias_constant, fault.onset_time) == (0.0, expected, 20.0)
    for u_lat in (-0.1, 0.0, 0.3):
        assert plant.actual_inputs([0.1, 0.05, u_lat, -0.01], 20.5)[LATERAL] == expected
    assert plant.actual_inputs([0.1, 0.05, 0.3, -0.01], 19.9)[LATERAL] != expected    # not before
    assert plant.stuck(20.0) and not plant.stuck(19.9)


def test_an_injection_sticks_in_place_or_is_refused_for_another_uh():
    class Msg:
        uh_id, channel, rho, bias_constant, bias_amplitude, bias_frequency, onset_time = 4, 3, 1.0, 0.0, 0.0, 0.0, 0.0
        stuck_in_place = True
    plant = plant_from_scenario(load_scenario('paper'), 4)
    command = np.array([0.1, 0.05, 0.0, 0.012])
    fault = inject(plant, Msg(), 4, command, 12.0)
    assert fault.is_stuck and fault.bias_constant == 0.012 and fault.onset_time == 12.0
    with pytest.raises(FaultError, match='names uh4 but arrived on /uh2/fault'):
        inject(plant, Msg(), 2, command, 12.0)


def test_the_in_process_run_sticks_the_actuator_at_its_event_step(lateral_run_staying):
    scenario, run = lateral_run_staying
    lateral = run.commands[:, 0, LATERAL]
    assert np.ptp(lateral[STUCK_STEP:]) > 0.01          # the controller keeps commanding it ...
    # ... and, stuck where command 2499 left it, the UH drifts away (no isolator answer: on_unable stay)
    assert np.linalg.norm(run.errors[-1, :1]) > 10.0
    assert run.stuck_uhs == (1,) and run.events.leaving == {}


# -- the isolator finds it: the effectiveness floor ----------------------------------------------------------
def test_the_isolator_finds_a_stuck_lateral_cyclic_below_the_floor_within_two_seconds(lateral_run_staying):
    scenario, run = lateral_run_staying
    spec = scenario.resilience
    found = first_unable(run.arrays(), scenario, 'proposed', spec.unable_rho, spec.unable_spread, scenario.ids)
    assert set(found) == {1} and found[1][1] == LATERAL
    # measured 1.41 s after (docs/resilience.md#measured-a-stuck-actuator); 2 s leaves room for a change of gains
    assert STUCK_STEP < found[1][0] < STUCK_STEP + 200


@pytest.mark.parametrize('name', ['paper', 'wide', 'square', 'swap', 'crowd'])
def test_no_fault_of_the_bundled_scenarios_is_taken_for_one_the_law_cannot_compensate(name):
    """Their faults keep rho >= 0.75; UH7's sinusoidal bias in `wide` reads rho 0.01 +- 0.48 (two bounds keep it)."""
    scenario = load_scenario(name)
    run = run_team_simulation(scenario, 'proposed')
    assert first_unable(run.arrays(), scenario, 'proposed', 0.5, 0.015, scenario.ids) == {}


#: Draws of campaign_paper_faults in which some UH's fit reads below the floor with no stuck actuator: a
#: sinusoidal bias the law cancels, or the observers' start (draw 40, no fault on that UH), found when the
#: command's spread is not asked (seven of the 19 in its first 100 draws; docs/resilience.md#leaving-the-team).
CONFOUNDED_DRAWS = (8, 11, 19, 24, 32, 39, 40)


def test_a_command_that_barely_moves_is_no_sign_of_a_stuck_actuator():
    from uh_campaign.resolve import resolve_scenario
    from uh_campaign.spec import load_spec
    from uh_topology.scenario import scenario_from_mapping
    spec = load_spec('campaign_paper_faults')
    without_spread = 0
    for draw in CONFOUNDED_DRAWS:
        scenario = scenario_from_mapping(resolve_scenario(spec, draw), source=spec.source)
        arrays = run_team_simulation(scenario, 'proposed').arrays()
        assert first_unable(arrays, scenario, 'proposed', 0.5, 0.015, scenario.ids) == {}, draw
        without_spread += bool(first_unable(arrays, scenario, 'proposed', 0.5, 0.0, scenario.ids))
    assert without_spread == len(CONFOUNDED_DRAWS)     # what the spread condition removes


def test_online_and_offline_isolators_find_the_same_step(lateral_run_staying):
    from uh_controller_node.isolation_runs import _setup
    scenario, run = lateral_run_staying
    arrays = run.arrays()
    nominal, settings, data = _setup(arrays, scenario, 'proposed', None)
    online = FaultIsolator(nominal, scenario.model_mismatch, float(scenario.dt), settings)
    for k in range(len(arrays['time'])):    # step by step, as a controller does
        online.update(data['time'][k], data['states'][k, 0], data['commands'][k, 0], data['fault_est_p'][k, 0],
                      data['fault_est_w'][k, 0])
        if online.unable(0.5, 0.015) >= 0:
            break
    assert (k, LATERAL) == first_unable(arrays, scenario, 'proposed', 0.5, 0.015, (1,))[1]


# -- leaving: the schedule, the tracker, the run -------------------------------------------------------------
def test_a_leaving_uh_declares_itself_and_its_states_carry_it_one_hop_per_step():
    scenario = stuck(1, 'lateral')
    schedule = loss_schedule(scenario, 6000, {1: (2598, LATERAL)})
    assert schedule.lost_at == {1: 2598} and schedule.leaves_from(1) == 2599
    # who receives UH1 (a declared or a standby edge) learns from its state 2599, the first to carry it; the
    # others a step later from one of them
    hears = {i for (i, j) in scenario.receivable_edges() if j == 1}
    assert hears and {2, 4} <= hears and hears != {2, 3, 4, 5}
    assert {i: schedule.known[(i, 1)] for i in (2, 3, 4, 5)} == {i: 2599 if i in hears else 2600 for i in (2, 3, 4, 5)}
    assert schedule.known[(1, 1)] == 2598
    assert schedule.view(1, 2598) == (frozenset(), frozenset())     # a UH's own declaration is not in its view
    hold = loss_schedule(stuck(1, 'lateral', 'resilience: {on_loss: hold}\n'), 6000, {1: (2598, LATERAL)})
    # with hold, only from UH1's own states: nothing is passed on
    assert {i: hold.known[(i, 1)] for i in (2, 3, 4, 5)} == {i: 2599 if i in hears else NEVER for i in (2, 3, 4, 5)}


def test_the_tracker_carries_its_own_declaration_also_with_hold():
    for reform in (True, False):
        tracker = LossTracker(2, (1,), 50, reform)
        tracker.declare_self(100)
        assert tracker.carried() == {2: 100}
        other = LossTracker(3, (2,), 50, reform)
        other.heard(2, 101, tracker.carried())
        other.update(101, {2: 101})
        assert 2 in other.known and (other.view()[1] if reform else other.view()[0]) == frozenset({2})


def test_the_leaving_uh_climbs_clear_and_the_rest_reform(lateral_run):
    scenario, run = lateral_run
    (declared, channel) = run.events.leaving[1]
    assert channel == LATERAL and STUCK_STEP < declared < STUCK_STEP + 200
    z0 = run.states[declared + 1, 0, 2]
    # it climbs leave_climb (5 m) above where it left and holds that height (its cyclic is stuck: it drifts)
    assert abs(run.states[-1, 0, 2] - (z0 + 5.0)) < 0.5
    # UH4 promoted to UH1's slot: every other UH within the re-forming thresholds over the last 10 s
    assert np.nanmax(run.errors[-1000:, 1:]) < 0.05
    # from the stuck on, no pair under the safety filter's 2 x rotor radius (1.6 m)
    assert closest_pair_series(run.states[STUCK_STEP:, :, :3]).min() > 1.6


def test_staying_with_the_fault_breaks_the_formation_where_leaving_keeps_it(lateral_run, lateral_run_staying):
    _, left = lateral_run
    _, stayed = lateral_run_staying
    assert np.nanmax(stayed.errors[-1000:]) > 1.0 > np.nanmax(left.errors[-1000:, 1:])


# -- the nodes: a lockstep run equals the in-process one ---------------------------------------------------------
@pytest.mark.dds
@pytest.mark.slow
def test_a_lockstep_distributed_run_with_a_stuck_actuator_equals_the_in_process_run(tmp_path):
    """UH1's lateral cyclic stuck at 8.3 s (just after the learning phase): the bag equals the in-process run.

    Its own controller finds it, declares itself, leaves; the others re-form. Equal to the bit, which fails
    if the simulator sticks the actuator elsewhere or a node declares, merges or leaves one step off.
    """
    from rosbags.rosbag2 import Reader
    from team_runs import assert_lockstep_run_equals_in_process

    from uh_runtime.messages import typestore
    text = paper_yaml('events:\n  - {time: 8.3, uh: 1, kind: stuck, channel: lateral}\nresilience: {}\n')
    scenario = parse_scenario(text, source='stuck.yaml')
    out, reference = assert_lockstep_run_equals_in_process(tmp_path, scenario, text, duration=10.5)
    declared = reference.events.leaving[1][0]
    assert declared < 1050
    roles, store = {}, typestore()
    with Reader(out / 'bag') as reader:
        statuses = [c for c in reader.connections if c.topic.startswith('/uh') and c.topic.endswith('/status')]
        for conn, _, raw in reader.messages(connections=statuses):
            msg = store.deserialize_cdr(raw, conn.msgtype)
            roles[int(msg.uh_id)] = (msg.role, [int(j) for j in msg.lost_uhs])
    assert roles[1] == ('leaving (lateral below rho 0.5)', [1])
    assert {i: roles[i] for i in (2, 3, 4, 5)} == {2: ('leader', [1]), 3: ('leader', [1]), 4: ('leader', [1]),
                                                   5: ('follower', [1])}


#: UH4's longitudinal cyclic stuck at 12-22 s, every 0.25 s, in process: found in all 40, within 3 s in 39 (the
#: other 3.46 s). The channels the study finds fastest have windows where they are not found at all (UH1's
#: lateral at 15.75 s, among others), and a realtime injection lands when it lands.
REALTIME_STUCK = (4, 'longitudinal', 3)


@pytest.mark.dds
@pytest.mark.slow
@pytest.mark.xfail(strict=False, reason='in real time the stuck actuator went unfound in 2 of 5 clean-clone runs '
                   '(docs/resilience.md#not-done-yet); the lockstep test above is the deterministic check')
def test_a_realtime_team_whose_actuator_is_stuck_at_run_time_lets_that_uh_leave_and_reforms(tmp_path):
    """``inject_fault.sh --stuck`` sticks UH4's longitudinal cyclic after 12 s of a realtime run with ``resilience``.

    UH4's controller finds it, declares itself and climbs clear; the others learn it from its states and
    re-form (UH5 alone in the leaders' hull); metrics.json's reconfiguration says so, from the bag.
    """
    import json
    import subprocess
    import time
    from pathlib import Path

    from team_runs import kill_session, start_run

    from uh_report.bag_metrics import read_team_bag
    from uh_runtime.network import reserve_domain_id
    from uh_team.reconfiguration import team_errors
    uh, channel, index = REALTIME_STUCK
    text = paper_yaml('resilience: {}\n')
    (tmp_path / 'team.yaml').write_text(text)
    scenario = parse_scenario(text, source='team.yaml')
    out, domain = tmp_path / 'run', reserve_domain_id()
    proc = start_run(out, domain, '--clock', 'realtime', '--rate', '2', '--duration', '32',
                     '--scenario', str(tmp_path / 'team.yaml'), '--no-visualization', '--no-report')
    try:
        deadline, log = time.monotonic() + 120, out / 'logs' / 'clock.log'
        while not (log.exists() and 'step 1280/' in log.read_text()):     # 12.8 s: the window of REALTIME_STUCK
            assert time.monotonic() < deadline and proc.poll() is None, 'step 1280 not reached'
            time.sleep(0.05)
        script = Path(__file__).resolve().parents[1] / 'scripts' / 'inject_fault.sh'
        sim_log = out / 'logs' / f'uh{uh}_sim.log'
        for _ in range(2):
            inject = subprocess.run([str(script), '--domain-id', str(domain), '--uh', str(uh), '--channel', channel,
                                     '--stuck', '--timeout', '60'], capture_output=True, text=True, timeout=120)
            assert inject.returncode == 0 and 'stays where it is' in inject.stderr, inject.stderr
            # a sample written while the simulator's reader has not yet matched the new writer is lost,
            # and acknowledged all the same (docs/faults.md#injecting-a-fault-at-run-time): send again once
            deadline = time.monotonic() + 3.0
            while f'fault injected on uh{uh}' not in sim_log.read_text() and time.monotonic() < deadline:
                time.sleep(0.05)
            if f'fault injected on uh{uh}' in sim_log.read_text():
                break
        output, _ = proc.communicate(timeout=300)
    finally:
        kill_session(proc)
    assert proc.returncode == 0, output
    assert sim_log.read_text().count(f'fault injected on uh{uh}') == 1, inject.stderr
    metrics = json.loads((out / 'metrics.json').read_text())
    (injected,) = metrics['faults']['injected']
    assert injected['stuck_in_place'] and injected['rho'] == 0.0 and injected['channel'] == index
    assert injected['received_s'] <= 22.0, injected      # in the window the in-process scan covers
    bag = read_team_bag(out / 'bag', scenario)
    assert set(bag['losses']['leaving']) == {uh}
    (event,) = metrics['reconfiguration']
    assert event['uh'] == uh and event['kind'] == 'unable' and event['promoted'] == {}
    # found within 5 s of the injection (at most 3.46 s in process), every UH knows within 1 s; re-formed: under
    # 0.05 m / 0.02 m from some step to the end (when is a realtime run's matter: on a loaded machine one late
    # sample over 0.02 m moves it, 3.3 s after the stuck in process, 13 s once in a loaded suite run)
    assert event['detected_at_s'] - injected['received_s'] <= 5.0, (event, injected)
    assert event['agreed_at_s'] - event['detected_at_s'] <= 1.0
    assert event['reformed_at_s'] is not None, event
    errors = team_errors(bag['states'][:, :, :3], bag['reference'][:, :3], scenario.reformed({uh}), scenario.ids)
    assert np.nanmax(errors[-200:, [0, 1, 2]]) < 0.05 and np.nanmax(errors[-200:, 4]) < 0.02
    # UH4 climbed leave_climb (5 m) above where it declared itself and holds that height (0.5 m: a realtime
    # run's hold, as in process); the team climbs 0.1 m/s under it, so it ends above every other UH
    declared = bag['losses']['leaving'][uh][0]
    z = bag['states'][:, uh - 1, 2]
    assert abs(z[-1] - (z[declared + 1] + 5.0)) < 0.5, (z[declared + 1], z[-1])
    others = [c for c in range(5) if c != uh - 1]
    assert z[-1] > np.max(bag['states'][-1, others, 2]) + 1.0
    assert metrics['rotor_overlap_s'] == 0.0
