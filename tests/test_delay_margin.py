"""The delay margin of a team and the delay remedies (docs/delay.md#delay-margin, docs/delay.md#remedies).

The linearised team model against the measured onset of the oscillation, the remedies
``reference_links: all_leaders`` and ``feedforward_weight``, their bad values, ``uh-analyze`` and the
departures a run records.
"""
import json
import re

import numpy as np
import pytest
import yaml
from scenario_texts import CONFIG, paper_yaml
from test_delay_compensation import _first_unstable_delay

from uh_controller_node.delay_margin import covering_feedforward_weight, scenario_link_age, scenario_margin
from uh_team import analyze_cli
from uh_team.delay_measure import OSCILLATION_RATE, measured_oscillation
from uh_team.departures import scenario_departures
from uh_team.metrics import metrics_from_arrays
from uh_team.team_simulation import run_team_simulation
from uh_topology import errors as E
from uh_topology.scenario import load_scenario, parse_scenario

LINKS = re.compile(r'reference_links:\n(  - .*\n)+')


def _all_leaders(extra: str = '') -> str:
    text = LINKS.sub('reference_links: all_leaders\n', paper_yaml())
    assert 'all_leaders' in text
    return text + ('\n' + extra if extra else '')


def _weighted(weight, extra: str = '') -> str:
    """Give the paper scenario with its gains inline and ``feedforward_weight: weight``."""
    gains = yaml.safe_load((CONFIG / 'paper_gains.yaml').read_text())['/**']['ros__parameters']
    gains['feedforward_weight'] = weight
    inline = yaml.safe_dump(gains, default_flow_style=True, width=10 ** 6).strip()
    return re.sub(r'gains: \S+', lambda _m: f'gains: {inline}', paper_yaml(extra))


@pytest.fixture(scope='module')
def paper_margin(paper):
    return scenario_margin(paper, 'proposed')


# -- the model against the measurement -------------------------------------------------------------

def test_the_paper_team_goes_unstable_at_5_steps_with_prediction_and_7_without(paper_margin):
    assert paper_margin.first_unstable == {'predict': 5, 'none': 7}
    assert paper_margin.margin_steps == {'predict': 4, 'none': 6}
    assert paper_margin.margin_ms('predict') == pytest.approx(40.0)
    mode = paper_margin.onset_mode['predict']
    # the ring's mode: about 2 Hz, horizontal, carried by the three leaders (the followers follow it)
    assert 1.5 < mode.frequency_hz < 2.5 and mode.axis == 'horizontal' and {1, 2, 3} <= set(mode.uhs)
    # the continuous-time ring model of docs/delay.md#why-the-ring-oscillates-from-ten-steps-on gives 6 / 9:
    # the sampled model of the whole team agrees with it within two steps
    assert abs(paper_margin.first_unstable['predict'] - _first_unstable_delay(predict=True)) <= 2
    assert abs(paper_margin.first_unstable['none'] - _first_unstable_delay(predict=False)) <= 2


@pytest.mark.parametrize('compensation, quiet, oscillating', [('predict', 5, 6), ('none', 6, 7)])
def test_the_measured_onset_is_within_two_steps_of_the_model(paper, paper_margin, compensation, quiet, oscillating):
    """Fly the paper team at the last quiet and the first oscillating delay (measured: 6 and 7)."""
    assert measured_oscillation(paper, 'proposed', quiet, compensation) < OSCILLATION_RATE
    # an oscillating run swings its roll and pitch rates by 2-3 rad/s, a settled one by 0.001-0.02
    assert measured_oscillation(paper, 'proposed', oscillating, compensation) > 10 * OSCILLATION_RATE
    assert abs(paper_margin.first_unstable[compensation] - oscillating) <= 2


def test_every_leader_hearing_the_reference_lifts_the_margin_past_twenty_steps():
    scenario = parse_scenario(_all_leaders(), source='all.yaml')
    assert scenario.reference_links_rule == 'all_leaders'
    assert list(scenario.adjacency[1:4, 0]) == [1.0, 1.0, 1.0]
    margin = scenario_margin(scenario, 'proposed', most=30)
    assert margin.margin_steps == {'predict': 29, 'none': None}     # none: stable to 30 steps at least
    assert measured_oscillation(scenario, 'proposed', 20, 'predict') < OSCILLATION_RATE   # measured: holds at 20


def test_a_lower_feedforward_weight_widens_the_margin_and_the_covering_weight_covers(paper):
    margins = [scenario_margin(parse_scenario(_weighted(w), source='w.yaml'), 'proposed', most=25,
                               compensations=('predict',)).margin_steps['predict'] for w in (1.0, 0.9, 0.8, 0.7)]
    assert margins[0] == 4 and all(b > a for a, b in zip(margins, margins[1:], strict=False)), margins
    weight = covering_feedforward_weight(paper, 'proposed', 20)
    assert weight is not None and weight < 1.0
    assert scenario_margin(paper, 'proposed', most=20, feedforward_weight=weight,
                           compensations=('predict',)).first_unstable['predict'] is None
    assert scenario_margin(paper, 'proposed', most=20, feedforward_weight=weight + 0.05,
                           compensations=('predict',)).first_unstable['predict'] is not None   # the largest on the grid


# -- the remedies in the law and the runs ----------------------------------------------------------

def test_feedforward_weight_one_is_the_paper_law_bit_for_bit_and_below_one_changes_it():
    plain = run_team_simulation(parse_scenario(paper_yaml(), source='p'), 'proposed', duration=2.0)
    one = run_team_simulation(parse_scenario(_weighted(1.0), source='p'), 'proposed', duration=2.0)
    less = run_team_simulation(parse_scenario(_weighted(0.8), source='p'), 'proposed', duration=2.0)
    assert np.array_equal(plain.commands, one.commands) and np.array_equal(plain.states, one.states)
    assert not np.array_equal(plain.commands, less.commands)


def test_a_run_records_its_departures_in_metrics_json():
    for text, expected in ((paper_yaml(), {}), (_all_leaders(), {'reference_links': 'all_leaders'}),
                           (_weighted(0.7), {'feedforward_weight': 0.7})):
        scenario = parse_scenario(text, source='d')
        run = run_team_simulation(scenario, 'case1', duration=1.0)
        assert metrics_from_arrays(run.arrays(), scenario, 'case1')['departures'] == expected
        assert scenario_departures(scenario, 'case1') == expected


def test_the_link_age_is_the_largest_delay_plus_jitter():
    assert scenario_link_age(parse_scenario(paper_yaml(), source='p')) == 0
    text = paper_yaml('impairments:\n  delay_steps: 3\n  jitter_steps: 2\n  links:\n'
                      '    - {uh: 4, hears: 1, delay_steps: 7, jitter_steps: 4}')
    assert scenario_link_age(parse_scenario(text, source='p')) == 11


BAD = [
    (lambda: _weighted(0.0), r"gains of scenario 'paper': feedforward_weight must be \(0, 1\], got 0\.0"),
    (lambda: _weighted(1.5), r"gains of scenario 'paper': feedforward_weight must be \(0, 1\], got 1\.5"),
    (lambda: LINKS.sub('reference_links: every_leader\n', paper_yaml()),
     r"^bad\.yaml:\d+: reference_links: 'every_leader' is not a rule; allowed: a list of links \{uh, weight\} "
     'or all_leaders$'),
]


@pytest.mark.parametrize('make, pattern', BAD)
def test_a_bad_remedy_is_refused_with_file_line_and_key(make, pattern):
    with pytest.raises(E.ScenarioError) as info:
        scenario = parse_scenario(make(), source='bad.yaml')
        scenario_margin(scenario)       # the gains are read when used
    assert re.search(pattern, str(info.value)), str(info.value)


# -- uh-analyze ------------------------------------------------------------------------------------

def test_uh_analyze_prints_the_margin_as_json(capsys):
    assert analyze_cli.main(['paper', '--json']) == 0
    result = json.loads(capsys.readouterr().out)
    assert result['margin_steps'] == {'none': 6, 'predict': 4}
    assert result['first_unstable_steps'] == {'none': 7, 'predict': 5}
    assert 0.5 < result['slowest_mode_s'] < 2.0          # every error mode decays at about k1 = 1 1/s
    assert result['links'] == {'oldest_state_steps': 0, 'compensation': 'predict', 'within_margin': True}
    assert result['departures'] == {} and result['covering_feedforward_weight'] == 1.0


def test_uh_analyze_says_when_the_links_exceed_the_margin(tmp_path, capsys):
    scenario = tmp_path / 'slow.yaml'
    scenario.write_text(paper_yaml('impairments: {delay_steps: 8}'))
    assert analyze_cli.main([str(scenario)]) == 0
    out = capsys.readouterr().out
    assert 'states up to 8 steps old (predict): BEYOND the margin' in out
    assert re.search(r'feed-forward weight\s+0\.\d+ covers', out), out


def test_uh_analyze_on_a_refused_scenario_gives_the_loaders_message(tmp_path, capsys):
    bad = tmp_path / 'bad.yaml'
    bad.write_text(LINKS.sub('reference_links: 7\n', paper_yaml()))
    assert analyze_cli.main([str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and re.search(r'bad\.yaml:\d+: reference_links: expected a list', err), err


# -- what a run says at start ----------------------------------------------------------------------

def test_uh_simulate_warns_in_one_line_when_the_links_exceed_the_margin(tmp_path, capsys):
    from uh_team import simulate_cli
    scenario = tmp_path / 'slow.yaml'
    scenario.write_text(paper_yaml('impairments: {delay_steps: 8}\nsafety: {enabled: false}'))
    assert simulate_cli.main(['--scenario', str(scenario), '--out', str(tmp_path / 'out'), '--duration', '1']) == 0
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith('uh-simulate: delay margin (predict): 4 steps (40 ms); the links deliver states up to 8 ')
    warnings = [line for line in err if 'warning' in line]
    assert warnings == ['uh-simulate: warning: the links deliver states up to 8 steps old, beyond the delay margin '
                        'of 4 steps (predict): expect the team to oscillate (docs/delay.md#remedies)']


def test_run_formation_says_the_margin_at_start_and_stays_quiet_without_delay(tmp_path, capsys):
    from uh_bringup import run_formation
    from uh_bringup.run_checks import check_run
    within = tmp_path / 'within.yaml'
    within.write_text(paper_yaml('impairments: {delay_steps: 3}'))
    for name, expected in (('paper', []), (str(within), ['[run] delay margin (predict): at least 4 steps; the links '
                                                         'deliver states up to 3 steps (30 ms) old (uh-analyze; '
                                                         'docs/delay.md#delay-margin)'])):
        args = run_formation.build_parser().parse_args(['--scenario', name, '--out', str(tmp_path / 'run'), '--force'])
        check_run(args)
        assert [line for line in capsys.readouterr().err.splitlines() if 'margin' in line] == expected


# -- delay_compensation: reference_motion ----------------------------------------------------------

def test_reference_motion_makes_the_prediction_exact_for_a_uh_flying_the_reference():
    """A UH at a fixed offset from the virtual leader: its delayed state, predicted, is its state now."""
    from uh_controller_node.impairments import add_reference_motion, predict_state
    from uh_core.reference import VirtualLeaderReference
    reference = VirtualLeaderReference(load_scenario('paper').reference)
    offset, dt, s, age = np.array([2.0, -1.0, 0.5]), 0.01, 3000, 25

    def state(step):
        x = np.zeros(12)
        x[0:3] = reference.at(step * dt).position + offset
        x[3:6] = reference.at(step * dt).velocity
        return x
    predicted = np.empty(12)
    predict_state(state(s), age, dt, predicted)
    lag = np.abs(predicted[:6] - state(s + age)[:6]).max()
    add_reference_motion(reference.row(s * dt), reference.row((s + age) * dt), age * dt, predicted)
    # exact in real numbers; a few roundings of numbers up to 30 m leave ~1e-14 m, the lag removed is ~3e-3 m
    assert np.abs(predicted[:6] - state(s + age)[:6]).max() < 1e-12 < 1e-3 < lag


def test_reference_motion_is_the_same_in_the_kernel_and_the_object_loop_and_recorded_as_a_departure():
    text = _all_leaders('impairments: {delay_steps: 12, jitter_steps: 4, loss: 0.2, '
                        'delay_compensation: reference_motion}')
    scenario = parse_scenario(text, source='rm.yaml')
    kernel = run_team_simulation(scenario, 'proposed', duration=2.0)
    objects = run_team_simulation(scenario, 'proposed', duration=2.0, engine='objects')
    for key in kernel.ARRAY_KEYS:
        assert np.array_equal(getattr(kernel, key), getattr(objects, key), equal_nan=True), key
    predicted = run_team_simulation(parse_scenario(text.replace('reference_motion', 'predict'), source='p'),
                                    'proposed', duration=2.0)
    assert not np.array_equal(kernel.commands, predicted.commands)   # it acts
    assert scenario_departures(scenario) == {'reference_links': 'all_leaders', 'delay_compensation': 'reference_motion'}
    # its terms come from the known trajectory and close no loop: the model gives it predict's margin
    assert analyze_cli.analysis(scenario, 'proposed', 35, False)['links']['within_margin'] is True


# -- /diagnostics in real time ---------------------------------------------------------------------

def test_a_realtime_controller_checks_ages_against_the_margin_of_the_compensation_it_applies(paper):
    from uh_controller_node.delay_margin import MarginWatch
    # without impairments a realtime controller uses states as they arrive: the margin without prediction
    watch = MarginWatch(paper, 'proposed')
    assert np.isnan(watch.margin_s(0.02)) and watch.stable_to == 2      # scanned only as far as the ages
    assert np.isnan(watch.margin_s(0.06)) and watch.margin_s(0.07) == pytest.approx(0.06)
    assert watch.first_unstable == 7 and watch.margin_s(0.3) == pytest.approx(0.06)
    predicted = MarginWatch(parse_scenario(paper_yaml('impairments: {delay_steps: 1}'), source='p'), 'proposed')
    assert predicted.margin_s(0.05) == pytest.approx(0.04)
    assert np.isnan(MarginWatch(parse_scenario(_all_leaders(), source='a'), 'proposed').margin_s(0.1))


def test_diagnostics_go_warn_when_a_neighbours_age_exceeds_the_delay_margin():
    from uh_core import diagnostics as D
    ages = (('uh1', 0.03, 0.05), ('uh3', 0.05, 0.09))
    beyond = D.controller_diagnostic(2, D.ControllerWindow(neighbour_ages=ages, delay_margin_s=0.06))
    assert beyond.level == D.WARN
    assert beyond.message == 'uh3 state up to 90 ms old, beyond the delay margin of 60 ms (docs/delay.md#delay-margin)'
    assert beyond.values['delay margin (s)'] == '0.06'
    within = D.controller_diagnostic(2, D.ControllerWindow(neighbour_ages=ages, delay_margin_s=0.1))
    unchecked = D.controller_diagnostic(2, D.ControllerWindow(neighbour_ages=ages))   # lockstep: NaN
    assert within.level == unchecked.level == D.OK and 'delay margin (s)' not in unchecked.values


# -- the report ------------------------------------------------------------------------------------

def test_the_report_gives_the_margin_and_flags_ages_beyond_it(tmp_path):
    import dataclasses

    from uh_report.delay_section import delay_section
    from uh_report.run_data import run_of_arrays
    delayed = parse_scenario(paper_yaml('impairments: {delay_steps: 3}'), source='d')
    run = run_of_arrays(tmp_path, delayed, 'proposed', {'neighbour_ages': {1: (0.031, 0.04), 4: (0.035, 0.06)}}, {})
    sentence, rows = delay_section(run)
    assert sentence.startswith('Delay margin of the team (predict; uh-analyze, docs/delay.md#delay-margin): 4 steps '
                               '(40 ms). The scenario\'s links deliver states up to 3 steps (30 ms) old.')
    assert rows == [['uh1', '31.0', '40.0', 'yes'], ['uh4', '35.0', '60.0', 'NO']]
    # a realtime run without impairments: the controllers predict nothing, so the margin is that of none
    plain = dataclasses.replace(run_of_arrays(tmp_path, load_scenario('paper'), 'proposed',
                                              {'neighbour_ages': {2: (0.004, 0.07)}}, {}), clock='realtime')
    assert delay_section(plain) == ('Delay margin of the team (none; uh-analyze, docs/delay.md#delay-margin): '
                                    '6 steps (60 ms). The scenario\'s links deliver states up to 0 steps (0 ms) old.',
                                    [['uh2', '4.0', '70.0', 'NO']])
    quiet = run_of_arrays(tmp_path, load_scenario('paper'), 'proposed', {'neighbour_ages': {2: (0.0, 0.01)}}, {})
    assert delay_section(quiet) is None      # no delayed link, nothing older than a step: no section


def test_run_json_records_the_departures_of_a_run_and_of_a_launch(tmp_path):
    import json

    from uh_bringup import launch_run, run_formation
    from uh_bringup.run_outcome import run_info
    args = run_formation.build_parser().parse_args(['--scenario', 'paper'])
    scenario = parse_scenario(_all_leaders(), source='a')
    assert run_info(args, 60.0, 42, 0, True, scenario_departures(scenario))['departures'] == {
        'reference_links': 'all_leaders'}
    assert run_info(args, 60.0, 42, 0, True)['departures'] == {}
    options = launch_run.check_arguments({name: default for name, default, _ in launch_run.ARGUMENTS}
                                         | {'out': str(tmp_path / 'launch')})
    launch_run.write_launch_record(options, 60.0, True, environ={}, departures={'feedforward_weight': 0.8})
    assert json.loads((tmp_path / 'launch' / 'run.json').read_text())['departures'] == {'feedforward_weight': 0.8}
