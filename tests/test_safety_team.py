"""The safety filter in a team run (docs/safety.md): it keeps rotors apart, and it is off bit for bit.

In process, both engines (the numba team loop and the per-UH objects the nodes run) run the same
filter on the same proximity input, so they agree to the bit; a filter that never acts changes
nothing; the head-on swap collides without the filter and passes with it.
"""
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from uh_bringup import run_formation
from uh_core.airframe import load_helicopter_params
from uh_team.separation_metrics import closest_approach, closest_pair_series
from uh_team.team_simulation import run_team_simulation
from uh_topology.scenario import load_scenario

ROTOR_OVERLAP = 2.0 * load_helicopter_params('helicopter').rotor_radius      # 1.6 m


def _closest(run) -> float:
    return closest_approach(run.time, run.states[:, :, :3], run.ids)['distance_m']


def test_the_head_on_swap_collides_without_the_filter_and_passes_with_it():
    off = run_team_simulation(load_scenario('swap', safety=False), duration=20.0)
    on = run_team_simulation(load_scenario('swap', safety=True), duration=20.0)
    assert _closest(off) < 0.5                          # the hubs meet at the midpoint
    assert not off.safety_active.any()
    separation = load_scenario('swap', safety=True).safety.separation(ROTOR_OVERLAP / 2.0)
    # the barrier keeps the minimum separation; 1 cm for the discrete step and the attitude loop's lag
    assert _closest(on) >= separation - 0.01
    assert on.safety_active.any()
    # ... and the pair does not stop nose to nose: both reach the other's place (formation error < 5 cm)
    assert np.abs(on.errors[-1]).max() < 0.05


def test_far_apart_the_filter_never_acts_and_the_run_is_the_laws_bit_for_bit(tmp_path):
    # the swap's two UHs sent away from each other: never within the sensing radius (12 m)
    text = Path(load_scenario('swap').source).read_text()
    text = text.replace('offset: [6.0, 0.0, 0.0], initial_state: {position: [-6.0',
                        'offset: [-20.0, 0.0, 0.0], initial_state: {position: [-20.0')
    text = text.replace('offset: [-6.0, 0.0, 0.0], initial_state: {position: [6.0',
                        'offset: [20.0, 0.0, 0.0], initial_state: {position: [20.0')
    (tmp_path / 'paper_gains.yaml').write_text(load_scenario('paper').gains_path.read_text())
    path = tmp_path / 'apart.yaml'
    path.write_text(text)
    off = run_team_simulation(load_scenario(path, safety=False), duration=5.0)
    on = run_team_simulation(load_scenario(path, safety=True), duration=5.0)
    assert closest_pair_series(on.states[:, :, :3]).min() > 12.0
    assert not on.safety_active.any()
    for key in ('states', 'commands', 'u_p', 'z1', 'fault_est_p', 'fault_est_w'):
        assert np.array_equal(getattr(on, key), getattr(off, key)), key


@pytest.mark.parametrize('scenario', ['paper', 'wide'])
def test_both_engines_run_the_same_filter_bit_for_bit(scenario):
    kernel = run_team_simulation(load_scenario(scenario, safety=True), duration=4.0, engine='kernel')
    objects = run_team_simulation(load_scenario(scenario, safety=True), duration=4.0, engine='objects')
    assert kernel.safety_active.any()                  # the first seconds bring UHs together
    for key in ('states', 'commands', 'u_p', 'z1', 'safety_active'):
        assert np.array_equal(getattr(kernel, key), getattr(objects, key)), key


@pytest.mark.parametrize('scenario', ['paper', 'wide'])
def test_with_the_filter_no_rotor_disks_overlap(scenario):
    off = run_team_simulation(load_scenario(scenario, safety=False), duration=8.0)
    on = run_team_simulation(load_scenario(scenario, safety=True), duration=8.0)
    assert _closest(off) < ROTOR_OVERLAP               # the paper's law alone: 0.83 m (paper), 0.66 m (wide)
    assert _closest(on) >= ROTOR_OVERLAP


def _simulate(tmp_path, *args):
    return subprocess.run([sys.executable, '-P', '-m', 'uh_team.simulate_cli', '--out', str(tmp_path), *args],
                          capture_output=True, text=True, timeout=300)


def test_uh_simulate_says_at_the_end_when_the_laws_rotors_overlapped(tmp_path):
    off = _simulate(tmp_path / 'off', '--scenario', 'swap', '--duration', '10', '--safety', 'off')
    assert off.returncode == 0, off.stderr
    last = off.stderr.strip().splitlines()[-1]
    assert last.startswith("uh-simulate: warning: the paper's law alone (safety off) let rotors touch: UH1-UH2 "
                           'came within 0.07 m, rotor disks overlapping (under 1.60 m) for ')
    metrics = json.loads((tmp_path / 'off' / 'metrics.json').read_text())
    assert metrics['rotor_overlap_s'] > 0 and metrics['safety_active_s'] == 0.0
    on = _simulate(tmp_path / 'on', '--scenario', 'swap', '--duration', '10', '--safety', 'on')
    assert on.returncode == 0, on.stderr
    assert 'rotors touch' not in on.stderr and 'overlapping' not in on.stderr
    metrics = json.loads((tmp_path / 'on' / 'metrics.json').read_text())
    assert metrics['rotor_overlap_s'] == 0.0 and metrics['separation_violation_s'] == 0.0
    assert metrics['safety_active_s'] > 0 and metrics['min_separation_pair'] == 'UH1-UH2'


def test_uh_simulate_refuses_a_bad_safety_value(tmp_path):
    result = _simulate(tmp_path, '--safety', 'maybe')
    assert result.returncode == 2
    # argparse quotes the choices since Python 3.12.8 / 3.11.11: accept both spellings
    assert re.search(r"argument --safety: invalid choice: 'maybe' \(choose from '?on'?, '?off'?\)", result.stderr)
    assert result.stderr.count('\n') == 1


def test_a_team_run_takes_safety_on_or_off_and_refuses_anything_else(tmp_path, capsys):
    from uh_bringup import compare
    assert run_formation.build_parser().parse_args(['--safety', 'on']).safety == 'on'
    with pytest.raises(SystemExit) as exited:
        run_formation.main(['--safety', 'maybe', '--out', str(tmp_path / 'run')])
    assert exited.value.code == 2 and "argument --safety: invalid choice: 'maybe'" in capsys.readouterr().err
    assert not (tmp_path / 'run').exists()              # nothing started
    # compare.sh hands --safety to each of its three team runs
    args = compare.build_parser().parse_args(['--safety', 'on'])
    for label, argv in compare._commands(args, tmp_path / 'cmp')[:3]:
        assert argv[argv.index('--safety') + 1] == 'on', label


def test_compare_runs_the_filter_in_process(tmp_path):
    from uh_bringup import compare
    assert compare.main(['--simulate', '--safety', 'on', '--duration', '3', '--out', str(tmp_path / 'sim')]) == 0
    for case in ('proposed', 'case1', 'case2'):
        metrics = json.loads((tmp_path / 'sim' / case / 'metrics.json').read_text())
        assert metrics['safety_active_s'] > 0 and metrics['rotor_overlap_s'] == 0.0


def test_a_uh_whose_samples_are_missing_leaves_its_pairs_out_of_the_separation():
    # a real-time run whose UH3 simulator died: its states are NaN from sample 2 on (not recorded)
    time = np.arange(4) * 0.01
    positions = np.array([[[0.0, 0, 0], [5.0, 0, 0], [0.5, 0, 0]],
                          [[0.0, 0, 0], [4.0, 0, 0], [0.6, 0, 0]],
                          [[0.0, 0, 0], [3.0, 0, 0], [np.nan] * 3],
                          [[0.0, 0, 0], [2.0, 0, 0], [np.nan] * 3]])
    closest = closest_approach(time, positions, (1, 2, 3))
    assert closest == {'distance_m': 0.5, 'pair': 'UH1-UH3', 'time_s': 0.0}
    series = closest_pair_series(positions)
    assert np.allclose(series, [0.5, 0.6, 3.0, 2.0])        # UH1-UH2 only, once UH3 is missing
    assert closest_approach(time, np.full((4, 2, 3), np.nan), (1, 2))['distance_m'] is None
    assert np.isnan(closest_pair_series(np.full((4, 2, 3), np.nan))).all()


def test_after_settle_metrics_with_nothing_recorded_are_none_without_numpy_warnings():
    import types
    import warnings

    from uh_team import metric_registry
    values = types.SimpleNamespace(after=np.array([False, True, True]))
    errors = np.array([[0.1, 0.2], [np.nan, np.nan], [np.nan, np.nan]])
    with warnings.catch_warnings():
        warnings.simplefilter('error')              # "Mean of empty slice" would fail the test
        assert metric_registry._after_settle_rms(errors, values) is None
        errors[2, 0] = 0.3
        assert metric_registry._after_settle_rms(errors, values) == pytest.approx(0.3)
