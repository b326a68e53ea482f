"""Losing a helicopter (docs/resilience.md): events and resilience keys, the repair rule, agreement, the runs."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scenario_texts import paper_yaml

from uh_controller_node.impairments import delivered_step
from uh_controller_node.loss_tracker import LossTracker
from uh_team.metrics import metrics_from_arrays
from uh_team.reconfiguration import REFORMED_CONTAINMENT_M, REFORMED_FORMATION_M
from uh_team.separation_metrics import separation_limits
from uh_team.team_events import NEVER, loss_schedule
from uh_team.team_simulation import SimulationError, run_team_simulation
from uh_topology import errors as E
from uh_topology.losses import loss_impairments
from uh_topology.reform import bypass_standby_edges, declared_edges, reformed_team
from uh_topology.scenario import parse_scenario
from uh_topology.scenario_keys import STALE_TIMEOUT
from uh_wire import wire
from uh_wire.run_config import DEFAULT_STALE_TIMEOUT

ROOT = Path(__file__).resolve().parents[1]
EVENT_STEP = 3000     # t = 30 s at dt = 0.01 s


def lost(uh: int, extra: str = '', time: float = 30.0):
    """Give the paper scenario with UH ``uh`` lost at ``time`` and ``extra`` keys."""
    return parse_scenario(paper_yaml(f'events:\n  - {{time: {time}, uh: {uh}, kind: lost}}\n{extra}'),
                          source='lost.yaml')


# -- bad input: one line naming the file, line and key ------------------------------------------------------
@pytest.mark.parametrize('text, error, where', [
    ('events:\n  - {time: 30.0, uh: 9, kind: lost}\n', E.UnknownIdError, 'events[0].uh'),
    ('events:\n  - {time: 60.0, uh: 2, kind: lost}\n', E.InvalidValueError, 'events[0].time'),
    ('events:\n  - {time: 0.0, uh: 2, kind: lost}\n', E.InvalidValueError, 'events[0].time'),
    ('events:\n  - {time: 3.0, uh: 2, kind: vanished}\n', E.InvalidValueError, 'events[0].kind'),
    ('events:\n  - {time: 3.0, uh: 2}\n', E.MissingFieldError, 'events[0]'),
    ('events:\n  - {time: 3.0, uh: 2, kind: lost}\n  - {time: 4.0, uh: 2, kind: lost}\n', E.InvalidValueError,
     'events[1].uh'),
    ('events: {time: 3.0}\n', E.WrongTypeError, 'events'),
    ('resilience: {standby_edges: [{uh: 1, hears: 7}]}\n', E.UnknownIdError, 'resilience.standby_edges[0].hears'),
    ('resilience: {standby_edges: [{uh: 1, hears: 3}]}\n', E.InvalidValueError, 'resilience.standby_edges[0]'),
    ('resilience: {standby_edges: [{uh: 4, hears: 0}, {uh: 4, hears: 0}]}\n', E.InvalidValueError,
     'resilience.standby_edges[1]'),
    ('resilience: {standby_edges: [{uh: 4, hears: 4}]}\n', E.InvalidValueError, 'resilience.standby_edges[0].hears'),
    ('resilience: {standby_edges: all}\n', E.InvalidValueError, 'resilience.standby_edges'),
    ('resilience: {on_loss: pray}\n', E.InvalidValueError, 'resilience.on_loss'),
    ('resilience: {lost_timeout: 0.2}\n', E.InvalidValueError, 'resilience.lost_timeout'),
    ('impairments: {delay_steps: 60}\nresilience: {lost_timeout: 0.5}\n', E.InvalidValueError,
     'resilience.lost_timeout'),
    ('events:\n  - {time: 0.004, uh: 2, kind: lost}\n', E.InvalidValueError, 'events[0].time'),   # step 0
    # 0.85^30 > 1e-12: a live link would be declared lost by a run of lost states
    ('impairments: {loss: 0.85}\nresilience: {lost_timeout: 0.3}\n', E.InvalidValueError, 'resilience.lost_timeout'),
    ('impairments: {dropouts: [{uh: 2, time: 3.0}]}\nresilience: {}\n', E.InvalidValueError, 'resilience'),
])
def test_bad_events_and_resilience_are_one_line_naming_file_line_and_key(text, error, where):
    with pytest.raises(error) as info:
        parse_scenario(paper_yaml(text), source='team.yaml')
    message = str(info.value)
    assert message.startswith('team.yaml:') and f': {where}: ' in message and '\n' not in message, message


def test_the_lost_timeout_floor_is_the_stale_timeout_of_the_nodes():
    assert STALE_TIMEOUT == DEFAULT_STALE_TIMEOUT


def test_no_events_no_resilience_and_no_standby_edges(paper):
    assert paper.events == () and paper.resilience is None and paper.standby_edges() == ()


# -- the repair rule -------------------------------------------------------------------------------------------
def test_bypass_standby_edges_of_the_paper_graph(paper):
    # worked out by hand from docs/resilience.md#the-rule: e.g. UH4 takes the slot of UH1 (nearest follower
    # place), so it must hear UH1's in-neighbour UH3 and the virtual leader, and UH2 (which heard UH1) hears UH4
    assert bypass_standby_edges(paper) == ((1, 5), (2, 4), (3, 4), (4, 0), (4, 3), (5, 1), (5, 2))


@pytest.mark.parametrize('uh, promoted, leaders, followers', [
    (1, {1: 4}, (2, 3, 4), (5,)), (2, {2: 4}, (1, 3, 4), (5,)), (3, {3: 5}, (1, 2, 5), (4,)),
    (4, {}, (1, 2, 3), (5,)), (5, {}, (1, 2, 3), (4,))])
def test_every_single_loss_of_the_paper_team_is_repaired(uh, promoted, leaders, followers):
    scenario = lost(uh)
    team = scenario.reformed({uh})
    assert (team.promoted, team.leaders, team.followers, team.holding) == (promoted, leaders, followers, {})
    assert set(team.edges) <= scenario.receivable_edges()
    # Lemma 1 again: the followers' targets are convex combinations of the leaders
    assert np.all(team.containment_weights >= 0.0)
    assert np.allclose(team.containment_weights.sum(axis=1), 1.0)
    for i in team.leaders:     # leaders hear only leaders and the virtual leader
        assert all(j == 0 or j in team.leaders for (r, j) in team.edges if r == i)


def test_without_standby_edges_the_loss_of_the_only_reference_link_leaves_no_team(paper):
    team = reformed_team(paper, {1}, declared_edges(paper))
    assert team.leaders == () and team.followers == ()
    assert set(team.holding) == {2, 3, 4, 5}
    assert team.holding[5] == 'no leader left with a path'


def test_the_rule_holds_the_uhs_it_cannot_place_and_flies_the_others(paper):
    # UH2 lost, declared edges only: UH4 takes slot 2 and hears UH1 (slot 2's in-neighbour, an edge it has as a
    # follower); UH3 heard slot 2 and cannot hear UH4 without a standby edge: it holds
    team = reformed_team(paper, {2}, declared_edges(paper))
    assert team.holding == {3: 'no path from the virtual leader through leaders'}
    assert team.leaders == (1, 4) and team.followers == (5,)


def test_a_promotion_the_edges_cannot_serve_gives_way_to_one_they_can():
    # UH1 and UH2 lost: the cheapest promotion (UH4 to slot 1, UH5 to slot 2) leaves UH4, UH5 and UH3 without a
    # path through the bypass standby edges; swapping them leaves only UH3 holding (it needs an edge no single
    # loss needs)
    scenario = lost(1, 'resilience: {}\n')
    team = scenario.reformed({1, 2})
    assert team.promoted == {1: 4, 2: 5} and team.leaders == (4, 5)
    assert set(team.holding) == {3}


def test_every_uh_computes_the_same_team_whatever_order_it_lists_the_lost(paper):
    a = reformed_team(paper, [3, 1])
    b = reformed_team(paper, {1, 3})
    assert (a.leaders, a.followers, a.edges, a.promoted) == (b.leaders, b.followers, b.edges, b.promoted)


# -- detection and agreement -------------------------------------------------------------------------------------
def test_agreement_follows_the_graph_one_step_per_hop():
    scenario = lost(2)
    lost_steps = scenario.resilience.lost_steps(scenario.dt)
    schedule = loss_schedule(scenario, 6000)
    # UH2's last state was sent at step 2999; its receivers declare it lost when that is lost_steps old
    hearers = {i for (i, j) in scenario.receivable_edges() if j == 2}
    assert {i for (i, j), s in schedule.declared.items() if j == 2} == hearers
    assert all(schedule.declared[(i, 2)] == EVENT_STEP - 1 + lost_steps for i in hearers)
    # the others learn from the first state sent by a neighbour that knew: one step per hop
    for i in set(scenario.ids) - hearers - {2}:
        sources = [m for (r, m) in scenario.receivable_edges() if r == i and m not in (0, 2)]
        assert schedule.known[(i, 2)] == min(schedule.known[(m, 2)] for m in sources) + 1
    agreed = schedule.agreed_at(2, [1, 3, 4, 5])
    assert agreed - EVENT_STEP <= round(1.0 / scenario.dt)          # goal: agreed within 1 s


def test_delayed_links_delay_the_agreement_by_their_delay_per_hop():
    plain = loss_schedule(lost(2), 6000)
    delayed = loss_schedule(lost(2, 'impairments: {delay_steps: 10}\n'), 6000)
    assert delayed.agreed_at(2, [1, 3, 4, 5]) > plain.agreed_at(2, [1, 3, 4, 5])
    assert delayed.agreed_at(2, [1, 3, 4, 5]) - EVENT_STEP <= 100


def test_hold_merges_nothing_and_leaves_the_silent_neighbour_out_from_its_own_declaration():
    scenario = lost(2, 'resilience: {on_loss: hold}\n')
    schedule = loss_schedule(scenario, 6000)
    lost_steps = scenario.resilience.lost_steps(scenario.dt)
    assert schedule.view(3, 5999) == (frozenset({2}), frozenset())     # UH3 hears UH2: it leaves it out
    assert schedule.known[(3, 2)] == EVENT_STEP - 1 + lost_steps
    assert schedule.known[(1, 2)] == NEVER                             # nothing travels


# -- the runs ------------------------------------------------------------------------------------------------------
@pytest.fixture(scope='module')
def paper_run(paper):
    return run_team_simulation(paper)


@pytest.mark.parametrize('uh', [1, 2, 3, 4, 5])
def test_each_single_loss_of_the_paper_team_reforms_within_the_goals(uh, paper_run):
    scenario = lost(uh)
    run = run_team_simulation(scenario)
    c = list(scenario.ids).index(uh)
    # nothing differs up to the event ...
    assert np.array_equal(run.states[:EVENT_STEP + 1], paper_run.states[:EVENT_STEP + 1])
    # ... then the lost UH brakes at brake_accel along its velocity (its failsafe) and hovers where it stops
    speed = np.linalg.norm(run.states[EVENT_STEP:, c, 3:6], axis=1)
    steps = np.arange(len(speed))
    brake = scenario.safety.brake_accel * scenario.dt
    assert np.allclose(speed, np.maximum(speed[0] - brake * steps, 0.0), atol=1e-9)   # rounding only
    rest = EVENT_STEP + int(np.ceil(speed[0] / brake))
    assert np.all(run.states[rest:, c, :6] == run.states[-1, c, :6]) and np.all(run.states[rest:, c, 3:6] == 0.0)
    assert np.all(run.states[EVENT_STEP + 1:, c, 9:12] == 0.0)      # no body rates
    metrics = metrics_from_arrays(run.arrays(), scenario, 'proposed')
    assert metrics['departures'] == {'on_loss': 'reform'}
    (event,) = metrics['reconfiguration']
    assert event['agreed_at_s'] - 30.0 <= 1.0
    assert event['reformed_at_s'] is not None and event['reformed_at_s'] - 30.0 <= 10.0
    assert event['formation_error_after_m'] <= REFORMED_FORMATION_M
    assert event['containment_error_after_m'] <= REFORMED_CONTAINMENT_M
    assert metrics['min_separation_m'] >= separation_limits(scenario)['rotor_overlap_m']
    assert event['holding'] == {}


def test_holding_after_a_loss_leaves_the_formation_broken_where_reforming_restores_it():
    hold = run_team_simulation(lost(2, 'resilience: {on_loss: hold}\n'))
    metrics = metrics_from_arrays(hold.arrays(), lost(2, 'resilience: {on_loss: hold}\n'), 'proposed')
    (event,) = metrics['reconfiguration']
    assert metrics['departures'] == {}
    assert event['reformed_at_s'] is None and event['holding'] == {
        '3': 'no path from the virtual leader without UH(s) [2]'}
    assert event['formation_error_last_10s_m'] > 1.0     # UH3 held back while the team flew on


def test_a_scenario_without_events_has_no_reconfiguration(paper, paper_run):
    assert metrics_from_arrays(paper_run.arrays(), paper, 'proposed')['reconfiguration'] is None


def test_events_run_only_on_the_kernel_engine():
    with pytest.raises(SimulationError, match='kernel engine only'):
        run_team_simulation(lost(2), duration=0.1, engine='objects')


def test_a_realtime_run_refuses_events_before_starting_anything(tmp_path):
    (tmp_path / 'lost.yaml').write_text(paper_yaml('events:\n  - {time: 30.0, uh: 2, kind: lost}\n'))
    out = tmp_path / 'run'
    proc = subprocess.run([sys.executable, '-P', '-m', 'uh_bringup.run_formation', '--scenario',
                           str(tmp_path / 'lost.yaml'), '--clock', 'realtime', '--out', str(out)],
                          capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.strip().count('\n') == 0 and 'in real time kill a node instead' in proc.stderr
    assert not out.exists()


# -- the nodes: the tracker each controller runs, the lost set on the wire, a lockstep run ----------------------------
@pytest.mark.parametrize('extra', [
    '', 'impairments: {seed: 3, delay_steps: 3, jitter_steps: 2, loss: 0.1}\n',
    'resilience: {on_loss: hold}\n', 'impairments: {seed: 1, delay_steps: 10, loss: 0.2}\n'])
@pytest.mark.parametrize('losses', [((1, 1.0),), ((4, 1.0),), ((2, 1.0), (3, 1.2))])
def test_the_trackers_of_the_nodes_learn_what_the_in_process_schedule_says(losses, extra):
    """Pass the lost sets between LossTrackers as the states carry them, step by step, and compare.

    A lost UH's tracker stops at its event step, as its node does; the second case loses UH3 before
    it knows of UH2's loss.
    """
    events = ''.join(f'  - {{time: {t}, uh: {uh}, kind: lost}}\n' for uh, t in losses)
    scenario = parse_scenario(paper_yaml('events:\n' + events + extra), source='lost.yaml')
    steps = 300
    schedule = loss_schedule(scenario, steps)
    links = loss_impairments(scenario)
    spec = scenario.resilience
    lost_at = {e.uh: e.step for e in scenario.events}
    receives = {i: sorted(j for (r, j) in links.delays if r == i) for i in scenario.ids}
    trackers = {i: LossTracker(i, receives[i], spec.lost_steps(scenario.dt), spec.on_loss == 'reform')
                for i in scenario.ids}
    carried = {i: {0: {}} for i in scenario.ids}      # {sender: {sent step: the lost set its state carried}}
    learnt = {}
    for k in range(steps + 1):
        for i in scenario.ids:
            if k >= lost_at.get(i, steps + 1):          # lost: its controller runs no more
                continue
            newest = {j: delivered_step(k, links.delays[(i, j)], links.jitters[(i, j)], links.losses[(i, j)],
                                        links.drop_step(j, scenario.dt), links.seed, i, j) for j in receives[i]}
            for j, s in newest.items():
                trackers[i].heard(j, s, carried[j].get(s, {}))
            trackers[i].update(k, newest)
            for j in trackers[i].known:
                learnt.setdefault((i, j), k)
        for i in scenario.ids:      # the state sent at k + 1 carries what its UH knew after step k
            carried[i][k + 1] = trackers[i].carried()
    expected = {(i, j): s for (i, j), s in schedule.known.items() if s <= steps}
    assert learnt == expected
    assert learnt, 'nobody learnt of the loss'
    if len(losses) == 2 and spec.on_loss == 'reform':   # UH3, lost before it knew of UH2, is not waited for
        assert (3, 2) not in learnt and schedule.agreed_at(2, [1, 3, 4, 5]) < steps


def test_a_uh_that_hears_itself_declared_lost_leaves():
    tracker = LossTracker(3, (2,), lost_steps=50, reform=True)
    tracker.heard(2, 10, {3: 9})
    tracker.update(10, {2: 10})
    assert tracker.excluded == 10 and 3 not in tracker.known


def test_the_lost_set_travels_in_states_and_commands_and_a_malformed_one_is_refused():
    state = wire.state_to_msg(3, 150, 1.5, np.zeros(12), {2: 149, 1: 160})
    assert list(state.lost_uhs) == [1, 2] and wire.msg_lost(state) == {1: 160, 2: 149}
    command = wire.command_to_msg(3, 150, 1.5, np.zeros(4), {2: 149})
    assert wire.msg_lost(command) == {2: 149}
    assert wire.msg_lost(wire.state_to_msg(3, 0, 0.0, np.zeros(12))) == {}
    state.lost_steps = [1]
    with pytest.raises(wire.WireError, match='one step per UH'):
        wire.msg_lost(state)


@pytest.mark.dds
@pytest.mark.slow
def test_a_lockstep_distributed_run_with_a_loss_equals_the_in_process_run(tmp_path):
    """UH1, the only leader hearing the virtual leader, lost at 1 s on delayed, jittery, lossy links.

    Its followers' nodes declare it lost from the age of its last state, the lost set travels in the
    commands and states, UH4 is promoted to its slot and every node flies the re-formed team: the
    bag's states and commands equal the in-process run to the bit (which fails if any node detects,
    merges or re-forms one step off), and the states show the lost set spreading.
    """
    from rosbags.rosbag2 import Reader
    from team_runs import assert_lockstep_run_equals_in_process

    from uh_runtime.messages import typestore
    text = paper_yaml('events:\n  - {time: 1.0, uh: 1, kind: lost}\n'
                      'impairments: {seed: 3, delay_steps: 3, jitter_steps: 2, loss: 0.1}\n')
    scenario = parse_scenario(text, source='lost.yaml')
    out, reference = assert_lockstep_run_equals_in_process(tmp_path, scenario, text, duration=3.0)
    schedule = reference.events
    store, first = typestore(), {}
    with Reader(out / 'bag') as reader:
        states = [c for c in reader.connections if c.topic.startswith('/uh') and c.topic.endswith('/state')]
        for conn, _, raw in reader.messages(connections=states):
            msg = store.deserialize_cdr(raw, conn.msgtype)
            if 1 in msg.lost_uhs:
                first.setdefault(int(msg.uh_id), int(msg.step))
    # a UH's state carries the set from the step after its controller knew
    assert first == {i: schedule.known[(i, 1)] + 1 for i in (2, 3, 4, 5)}
    # the controllers' status says the lost set and each UH's role at the end: UH4 promoted to leader
    roles = {}
    with Reader(out / 'bag') as reader:
        statuses = [c for c in reader.connections if c.topic.startswith('/uh') and c.topic.endswith('/status')]
        for conn, _, raw in reader.messages(connections=statuses):
            msg = store.deserialize_cdr(raw, conn.msgtype)
            roles[int(msg.uh_id)] = (msg.role, [int(j) for j in msg.lost_uhs])
    assert roles == {1: ('lost', []), 2: ('leader', [1]), 3: ('leader', [1]), 4: ('leader', [1]),
                     5: ('follower', [1])}
    # the report: errors against the team in force (none for the lost UH), the graph before and after
    from uh_report.report import write_figures
    from uh_report.report_figures import uh_errors
    from uh_report.run_data import load_run
    run = load_run(out, 'paper')
    errors = uh_errors(run)
    assert np.isnan(errors[100:, 0]).all() and np.isfinite(errors[:100]).all()   # UH1 lost at step 100
    assert np.isfinite(errors[-1, 1:]).all()                                    # the others against the new team
    figures = write_figures([run], tmp_path / 'report', kinds={'topology', 'xy_snapshots'})
    assert set(figures[run.name]) == {'topology', 'xy_snapshots'}


def test_diagnostics_say_the_lost_set_and_the_role():
    from uh_core.diagnostics import ControllerWindow, controller_diagnostic
    report = controller_diagnostic(4, ControllerWindow(lost_uhs=(1,), role='leader'))
    assert report.values['role'] == 'leader' and report.values['lost UHs'] == 'uh1'
    assert report.message == 'team lost uh1; flying as leader'
    held = controller_diagnostic(3, ControllerWindow(lost_uhs=(2,), role='holding (no path)'))
    assert held.message.startswith('holding (no path)') and held.level > report.level
    assert 'role' not in controller_diagnostic(3, ControllerWindow()).values


@pytest.mark.dds
@pytest.mark.slow
def test_a_realtime_team_whose_simulator_is_killed_declares_agrees_and_reforms(tmp_path):
    """SIGKILL UH2's simulator at 6 s of a realtime run of the paper team with ``resilience`` (no events).

    Its neighbours declare it lost from the age of its last state, the lost set reaches every UH,
    UH4 takes slot 2 and the team re-forms; metrics.json's reconfiguration says when, from the bag.
    """
    import json
    import os
    import signal
    import time

    from team_runs import kill_session, start_run

    from uh_report.bag_metrics import read_team_bag
    from uh_runtime.network import reserve_domain_id
    from uh_team.reconfiguration import team_errors
    text = paper_yaml('resilience: {}\n')
    (tmp_path / 'team.yaml').write_text(text)
    scenario = parse_scenario(text, source='team.yaml')
    out = tmp_path / 'run'
    proc = start_run(out, reserve_domain_id(), '--clock', 'realtime', '--rate', '2', '--duration', '20',
                     '--scenario', str(tmp_path / 'team.yaml'), '--no-visualization', '--no-report')
    try:
        deadline, log = time.monotonic() + 120, out / 'logs' / 'clock.log'
        while not (log.exists() and 'step 600/' in log.read_text()):
            assert time.monotonic() < deadline and proc.poll() is None, 'step 600 not reached'
            time.sleep(0.05)
        os.kill(json.loads((out / 'run.json').read_text())['pids']['uh2_sim'], signal.SIGKILL)
        output, _ = proc.communicate(timeout=300)
    finally:
        kill_session(proc)
    assert proc.returncode == 3, output        # completed, with a node failure
    bag = read_team_bag(out / 'bag', scenario)
    last_uh2 = int(np.flatnonzero(~np.isnan(bag['states'][:, 1, 0]))[-1])
    lost_steps = scenario.resilience.lost_steps(scenario.dt)
    known = bag['losses']['known']
    assert set(known) == {(1, 2), (3, 2), (4, 2), (5, 2)}
    # declared from the age of the last state: not before lost_steps after it, and every UH knows within 1 s
    # (the bag's last UH2 state may be a step older than a controller's, and a loaded realtime controller
    # may skip a step or two: 3 steps of slack)
    assert all(last_uh2 + lost_steps - 3 <= step <= last_uh2 + 100 for step in known.values()), (last_uh2, known)
    metrics = json.loads((out / 'metrics.json').read_text())
    (event,) = metrics['reconfiguration']
    assert event['uh'] == 2 and event['promoted'] == {'2': 4} and event['agreed_at_s'] - event['time_s'] <= 1.0
    assert event['reformed_at_s'] is not None and event['reformed_at_s'] - event['time_s'] <= 10.0
    # the re-formed team's errors over the last 2 s: under the thresholds with room for a realtime run's jitter
    errors = team_errors(bag['states'][:, :, :3], bag['reference'][:, :3], scenario.reformed({2}), scenario.ids)
    assert np.nanmax(errors[-200:, [0, 2, 3]]) < 0.05 and np.nanmax(errors[-200:, 4]) < 0.02
    assert metrics['rotor_overlap_s'] == 0.0


def test_never_is_beyond_any_run():
    assert NEVER > 10 ** 12


def test_a_bag_recorded_before_the_lost_set_fields_still_reads():
    """The reader decodes a bag with the message definitions it recorded when they differ from today's."""
    from random_messages import random_message
    from rosbags.serde import SerdeError

    from uh_report.bag_metrics import bag_typestore
    from uh_runtime.messages import typestore
    name = 'uh_msgs/msg/ControllerStatus'
    text = (ROOT / 'uh_msgs' / 'msg' / 'ControllerStatus.msg').read_text()
    old = '\n'.join(line for line in text.splitlines() if not line.startswith(('uint32[] lost_uhs', 'string role')))
    assert bag_typestore({name: text}) is typestore()          # recorded as defined now: the project's store
    store = bag_typestore({name: old})
    assert [field for field, _ in store.fielddefs[name][1]][-1] == 'closest_uh'
    payload = store.serialize_cdr(random_message(np.random.default_rng(0), store, name, strings=False), name)
    assert int(store.deserialize_cdr(payload, name).uh_id) >= 0        # the bag's own definition reads it
    with pytest.raises(SerdeError):                                   # today's does not: it expects two more fields
        typestore().deserialize_cdr(payload, name)
