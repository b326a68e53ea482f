"""Campaigns that draw losses (docs/campaigns.md#losing-a-helicopter).

``draws.losses`` gives every draw one ``lost`` event (a UH and a time on a control step) from a stream
of its own, so the other draws of a campaign, and every existing campaign, resolve as before; the
top-level ``resilience`` flies the same draws with another answer; bad keys are one line with file,
line and key; a tiny campaign stores the loss columns, and a threshold on a column without a value
is not met.
"""
import hashlib
import re

import pytest

from uh_campaign import cli
from uh_campaign.runner import run_campaign, success_of
from uh_campaign.spec import load_spec, parse_spec, resolve_scenario, scenario_yaml
from uh_campaign.worker import run_task
from uh_team import campaign_store as store
from uh_topology import errors as E

#: The loss columns of the results file (uh_team.metric_registry).
LOSS_COLUMNS = ('reform_time_s', 'agree_time_s', 'loss_formation_last_10s_m', 'loss_containment_last_10s_m',
                'loss_min_separation_m')

#: sha256 of the resolved scenarios of draws 0-3 (every sweep value) of bundled campaigns, as they resolved
#: before draws.losses existed (commit f79f4f3): a scenario key, a generator and a sweep with impairments.
BEFORE_LOSSES = {
    'campaign_paper_faults': '200c9fea1b26d533aa8b5c8c8c62b770215366a195d62253fc7a977e9cae3672',
    'campaign_random_graphs': '538e9825db3675cbeaf7693c85c03d72a8a3f446ef0c981a0ca7cf78eb21132d',
    'campaign_delay_sweep': '9951119935f7a691da8f9e5b74f29b2ec02a733de0cc0351ef5dccf38be8f6cd',
}

GOOD_HEAD = 'name: bad\nscenario: paper\nruns: 2\nduration: 4.0\n'       # lines 1-4


def _write(directory, text, name='spec.yaml'):
    path = directory / name
    path.write_text(text)
    return path


def _resolved_digest(spec, draws=4) -> str:
    h = hashlib.sha256()
    for draw in range(draws):
        for s in range(len(spec.sweep_values)):
            h.update(scenario_yaml(resolve_scenario(spec, draw, s)).encode())
    return h.hexdigest()


# ----------------------------------------------------------------------------------------------
# The draw
# ----------------------------------------------------------------------------------------------
def test_a_drawn_loss_is_one_event_in_range_on_a_control_step_and_the_same_every_time():
    spec = load_spec('campaign_losses')
    assert (spec.draws.losses.time, spec.draws.losses.uhs) == ((15.0, 45.0), None)
    events = [resolve_scenario(spec, draw)['events'] for draw in range(60)]
    assert events == [resolve_scenario(spec, draw)['events'] for draw in range(60)]    # deterministic per draw
    assert resolve_scenario(spec, 41)['events'] == events[41]                          # in any order
    assert all(len(e) == 1 and e[0]['kind'] == 'lost' for e in events)
    times = [e[0]['time'] for e in events]
    assert all(15.0 <= t <= 45.0 and abs(t / 0.01 - round(t / 0.01)) < 1e-6 for t in times)
    assert {e[0]['uh'] for e in events} == {1, 2, 3, 4, 5}      # every UH of the team may be lost
    assert len(set(times)) > 50 and min(times) < 18.0 and max(times) > 42.0
    # a list of UHs and a fixed time
    narrow = parse_spec(spec.text.replace('time: [15.0, 45.0]', 'time: [20.0, 20.0]\n    uhs: [2, 4]'),
                        source=spec.source, base_dir=spec.base_dir)
    drawn = [resolve_scenario(narrow, draw)['events'][0] for draw in range(20)]
    assert {e['uh'] for e in drawn} == {2, 4} and {e['time'] for e in drawn} == {20.0}


def test_adding_losses_leaves_every_other_draw_as_it_was():
    for name, digest in BEFORE_LOSSES.items():
        assert _resolved_digest(load_spec(name)) == digest, name
    faults = load_spec('campaign_paper_faults')
    lossy = parse_spec(faults.text + '  losses: {time: [15.0, 45.0], uhs: [1, 3, 5]}\n', source=faults.source,
                       base_dir=faults.base_dir)
    for draw in range(8):
        plain, with_loss = resolve_scenario(faults, draw), resolve_scenario(lossy, draw)
        events = with_loss.pop('events')
        assert with_loss == plain and 'events' not in plain
        assert events[0]['uh'] in (1, 3, 5)


def test_a_stuck_campaign_draws_one_stuck_channel_per_draw_and_its_stay_twin_the_same_draws():
    spec, stay = load_spec('campaign_stuck'), load_spec('campaign_stuck_stay')
    events = [resolve_scenario(spec, draw)['events'] for draw in range(80)]
    assert all(len(e) == 1 and e[0]['kind'] == 'stuck' for e in events)
    assert {e[0]['channel'] for e in events} == {'collective', 'tail_rotor', 'lateral', 'longitudinal'}
    assert {e[0]['uh'] for e in events} == {1, 2, 3, 4, 5}
    assert all(15.0 <= e[0]['time'] <= 45.0 for e in events)
    for draw in (0, 7, 33):
        a, b = resolve_scenario(spec, draw), resolve_scenario(stay, draw)
        assert (a['resilience'], b['resilience']) == ({'on_unable': 'leave'}, {'on_unable': 'stay'})
        assert {k: v for k, v in a.items() if k not in ('name', 'description', 'resilience')} == \
            {k: v for k, v in b.items() if k not in ('name', 'description', 'resilience')}


def test_the_hold_campaign_flies_the_same_draws_holding():
    reform, hold = load_spec('campaign_losses'), load_spec('campaign_losses_hold')
    assert (reform.resilience, hold.resilience) == ({'on_loss': 'reform'}, {'on_loss': 'hold'})
    assert (reform.cases, reform.success) == (('proposed',), {'reform_time_s': 10.0, 'separation_violation_s': 0.0})
    assert hold.success == {'loss_formation_last_10s_m': 0.05, 'loss_containment_last_10s_m': 0.02,
                            'separation_violation_s': 0.0}
    for draw in range(10):
        a, b = resolve_scenario(reform, draw), resolve_scenario(hold, draw)
        assert (a.pop('resilience'), b.pop('resilience')) == ({'on_loss': 'reform'}, {'on_loss': 'hold'})
        for key in ('name', 'description'):
            a.pop(key), b.pop(key)
        assert a == b


def test_a_swept_resilience_value_is_written_over_the_specs_resilience(tmp_path):
    spec = load_spec(_write(tmp_path, GOOD_HEAD + 'resilience: {on_loss: hold, lost_timeout: 0.5}\n'
                                      'sweep: {parameter: resilience.lost_timeout, values: [0.5, 0.8]}\n'))
    assert resolve_scenario(spec, 1, 1)['resilience'] == {'on_loss': 'hold', 'lost_timeout': 0.8}


# ----------------------------------------------------------------------------------------------
# Bad input
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize('tail, error, line, key', [
    ('draws:\n  losses: [1.0, 2.0]\n', E.WrongTypeError, 6, 'draws.losses'),
    ('draws:\n  losses:\n    uhs: [2]\n', E.MissingFieldError, 6, 'draws.losses'),
    ('draws:\n  losses:\n    time: [1.0, 2.0]\n    uh: [2]\n', E.UnknownKeyError, 8, 'draws.losses.uh'),
    ('draws:\n  losses:\n    time: 2.0\n', E.WrongTypeError, 7, 'draws.losses.time'),
    ('draws:\n  losses:\n    time: [0.0, 3.0]\n', E.InvalidValueError, 7, 'draws.losses.time[0]'),
    ('draws:\n  losses:\n    time: [1.0, 4.0]\n', E.InvalidValueError, 7, 'draws.losses.time[1]'),
    ('draws:\n  losses:\n    time: [3.0, 1.0]\n', E.InvalidValueError, 7, 'draws.losses.time'),
    ('draws:\n  losses:\n    time: [1.001, 1.009]\n', E.InvalidValueError, 7, 'draws.losses.time'),
    ('draws:\n  losses:\n    time: [1.0, two]\n', E.WrongTypeError, 7, 'draws.losses.time[1]'),
    ('draws:\n  losses:\n    time: [1.0, 2.0]\n    uhs: 3\n', E.WrongTypeError, 8, 'draws.losses.uhs'),
    ('draws:\n  losses:\n    time: [1.0, 2.0]\n    uhs:\n      - 1\n      - 9\n', E.UnknownIdError, 10,
     'draws.losses.uhs[1]'),
    ('draws:\n  losses:\n    time: [1.0, 2.0]\n    uhs: [2, 2]\n', E.InvalidValueError, 8, 'draws.losses.uhs[1]'),
    ('draws:\n  losses: {time: [1.0, 2.0]}\nsweep: {parameter: \'events[0].time\', values: [1.5]}\n',
     E.InvalidValueError, 7, 'sweep.parameter'),
    ('resilience: reform\n', E.WrongTypeError, 5, 'resilience'),
    ('resilience:\n  timeout: 0.5\n', E.UnknownKeyError, 6, 'resilience.timeout'),
    ('resilience:\n  on_loss: retreat\n', E.InvalidValueError, 6, 'resilience.on_loss'),
    ('resilience:\n  lost_timeout: 0.2\n', E.InvalidValueError, 6, 'resilience.lost_timeout'),
    ('resilience:\n  standby_edges: [{uh: 1, hears: 3}]\n', E.InvalidValueError, 6, 'resilience.standby_edges[0]'),
    ('draws:\n  losses:\n    time: [1.0, 2.0]\n    kind: melted\n', E.InvalidValueError, 8, 'draws.losses.kind'),
    ('draws:\n  losses:\n    time: [1.0, 2.0]\n    channels: [lateral]\n', E.InvalidValueError, 8,
     'draws.losses.channels'),
    ('draws:\n  losses:\n    time: [1.0, 2.0]\n    kind: stuck\n    channels: [lateral, rudder]\n',
     E.InvalidValueError, 9, 'draws.losses.channels[1]'),
    ('draws:\n  losses:\n    time: [1.0, 2.0]\n    kind: stuck\n    channels: [2, lateral]\n',
     E.InvalidValueError, 9, 'draws.losses.channels[1]'),
    ('resilience:\n  on_unable: flee\n', E.InvalidValueError, 6, 'resilience.on_unable'),
])
def test_bad_loss_keys_are_refused_with_file_line_and_key(tmp_path, tail, error, line, key):
    spec = _write(tmp_path, GOOD_HEAD + tail)
    with pytest.raises(error) as info:
        load_spec(spec)
    assert (info.value.source, info.value.line, info.value.path) == (str(spec), line, key)
    assert str(info.value).startswith(f'{spec}:{line}: {key}: ')


def test_a_list_of_standby_edges_is_refused_with_a_generator(tmp_path):
    spec = _write(tmp_path, 'name: g\nruns: 1\ngenerator: {leaders: 2, followers: 2}\n'
                            'resilience:\n  standby_edges: [{uh: 3, hears: 1}]\n')
    with pytest.raises(E.InvalidValueError) as info:
        load_spec(spec)
    assert (info.value.line, info.value.path) == (5, 'resilience.standby_edges')


def test_the_cli_refuses_a_bad_loss_key_in_one_line_with_status_2(tmp_path, capsys):
    spec = _write(tmp_path, GOOD_HEAD + 'draws:\n  losses: {time: [1.0, 2.0], uhs: [6]}\n')
    assert cli.main([str(spec), '--out', str(tmp_path / 'out')]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert re.match(rf'uh-campaign: error: {re.escape(str(spec))}:6: draws\.losses\.uhs\[0\]: UH id 6 is not a UH', err)
    assert not (tmp_path / 'out').exists()


# ----------------------------------------------------------------------------------------------
# A tiny campaign
# ----------------------------------------------------------------------------------------------
TINY = """\
name: tiny_losses
scenario: paper
runs: 3
seed: 11
duration: 40.0
cases: [proposed]
success: {reform_time_s: 10.0, separation_violation_s: 0.0}
draws:
  position_spread: 0.5
  losses: {time: [15.0, 25.0]}
"""


def test_a_tiny_campaign_stores_the_loss_columns(tmp_path):
    spec = load_spec(_write(tmp_path, TINY))
    run_campaign(spec, tmp_path / 'out', workers=1)
    runs = store.read_runs(tmp_path / 'out' / store.DB_NAME)
    assert list(runs['status']) == ['ok'] * 3
    assert all(runs['agree_time_s'] == 0.5)                     # the paper graph: every UH knows 0.5 s after
    assert all((runs['reform_time_s'] > 0.5) & (runs['reform_time_s'] <= 10.0))
    assert all(runs['loss_min_separation_m'] > 1.6) and all(runs['loss_formation_last_10s_m'] < 0.05)
    expected = [success_of({'status': 'ok', **{m: runs[m][i] for m in spec.success}}, spec.success) for i in range(3)]
    assert list(runs['success']) == expected and any(expected)

    # holding: never re-formed, so a threshold on reform_time_s is not met; without events: no loss columns
    def row(text, draw=0):
        held = parse_spec(text, source=spec.source, base_dir=spec.base_dir)
        task = {'draw': draw, 'sweep_index': 0, 'sweep_value': None, 'scenario_file': 'x.yaml', 'cases': ['proposed'],
                'scenario_text': scenario_yaml(resolve_scenario(held, draw))}
        (result,) = run_task(task)
        assert result['status'] == 'ok', result['reason']
        return result

    hold = row(TINY + 'resilience: {on_loss: hold}\n')
    assert (hold['reform_time_s'], hold['agree_time_s']) == (None, None)
    assert hold['loss_formation_last_10s_m'] > 0.0 and hold['loss_min_separation_m'] > 0.0
    assert success_of(hold, spec.success) == 0 and success_of(hold, {}) == 1
    plain = row(TINY.replace('  losses: {time: [15.0, 25.0]}\n', '').replace('duration: 40.0', 'duration: 2.0'))
    assert all(plain[m] is None for m in LOSS_COLUMNS)
