"""The ``safety`` mapping of a scenario and the design-time separation check (docs/safety.md).

Bad input is one specific line naming the file, the line and the key; a formation or start closer
than two rotor radii is refused, closer than the minimum separation is a warning the scenario carries.
"""
import re
from pathlib import Path

import pytest

from uh_core.airframe import HelicopterParamsError, load_helicopter_params
from uh_topology.errors import ScenarioError
from uh_topology.safety import SafetySpec, close_pairs, default_min_separation, formation_points
from uh_topology.scenario import load_scenario, parse_scenario
from uh_topology.scenario_keys import SEPARATION_MARGIN

PAPER = Path(__file__).resolve().parents[1] / 'uh_topology' / 'uh_topology' / 'config' / 'paper.yaml'
AIRFRAME = Path(__file__).resolve().parents[1] / 'uh_core' / 'uh_core' / 'config' / 'helicopter.yaml'


def _paper(tmp_path, extra: str = '', replace: tuple = ()) -> Path:
    """Write the paper scenario as a file in ``tmp_path`` (its gains copied along), with ``extra`` appended."""
    text = PAPER.read_text()
    for old, new in replace:
        assert old in text
        text = text.replace(old, new)
    (tmp_path / 'paper_gains.yaml').write_text((PAPER.parent / 'paper_gains.yaml').read_text())
    path = tmp_path / 'paper.yaml'
    path.write_text(text + extra)
    return path


def _line_of(path: Path, needle: str) -> int:
    return next(n for n, line in enumerate(path.read_text().splitlines(), 1) if needle in line)


def test_the_bundled_airframe_has_a_rotor_of_0_8_m_and_the_default_separation_follows():
    rotor = load_helicopter_params('helicopter').rotor_radius
    assert rotor == 0.8
    assert default_min_separation(rotor) == pytest.approx(2 * 0.8 + SEPARATION_MARGIN)


def test_a_scenario_without_safety_has_the_defaults_and_the_filter_is_on():
    scenario = load_scenario('paper')
    assert scenario.safety == SafetySpec()
    assert scenario.safety.enabled is True             # on by default: rotors never touch
    assert scenario.separation_warnings == ()


def test_the_safety_keys_are_read(tmp_path):
    path = _paper(tmp_path, 'safety: {enabled: true, min_separation: 1.7, sensing_radius: 9.0, barrier_gain: 3.0}\n')
    safety = load_scenario(path).safety
    assert (safety.enabled, safety.min_separation, safety.sensing_radius, safety.barrier_gain) == (True, 1.7, 9.0, 3.0)


@pytest.mark.parametrize('safety, key, allowed', [
    ('{min_separation: 0.0}', 'safety.min_separation', 'allowed: > 0.0 (m)'),
    ('{min_separation: -1.0}', 'safety.min_separation', 'allowed: > 0.0 (m)'),
    ('{sensing_radius: 0}', 'safety.sensing_radius', 'allowed: > 0.0 (m)'),
    ('{min_separation: 2.0, sensing_radius: 1.9}', 'safety.sensing_radius', 'allowed: > min_separation'),
    ('{sensing_radius: 1.7}', 'safety.sensing_radius', 'allowed: > 1.75 m'),
    ('{min_separation: 1.5}', 'safety.min_separation', 'allowed: >= 1.6 m'),
    ('{enabled: 1}', 'safety.enabled', 'expected true or false'),
    ('{brake: 2.0}', 'safety.brake', "unknown key 'brake'"),
    ('{proximity_loss: 1.0}', 'safety.proximity_loss', 'allowed: [0.0, 1.0)'),
    ('{proximity_delay_steps: -1}', 'safety.proximity_delay_steps', 'out of range; allowed: >= 0'),
    ('{proximity_delay_steps: 2.5}', 'safety.proximity_delay_steps', 'a whole number of steps >= 0'),
    ('{proximity_noise_position: -0.1}', 'safety.proximity_noise_position', 'allowed: >= 0.0 (m)'),
    ('{proximity_seed: -3}', 'safety.proximity_seed', 'out of range; allowed: >= 0'),
])
def test_bad_safety_input_is_one_line_naming_the_file_line_and_key(tmp_path, safety, key, allowed):
    path = _paper(tmp_path, f'safety: {safety}\n')
    with pytest.raises(ScenarioError) as caught:
        load_scenario(path)
    message = str(caught.value)
    assert '\n' not in message
    assert message.startswith(f'{path}:{_line_of(path, "safety:")}: {key}')
    assert allowed in message


def test_formation_targets_closer_than_two_rotor_radii_are_refused_with_the_filter_on(tmp_path):
    # UH2's slot moved to 1.0 m from UH1's: the disks of the two leaders would overlap in formation
    path = _paper(tmp_path, 'safety: {enabled: true}\n',
                  replace=(('offset: [-1.5, 2.598076211353316, 0.0]', 'offset: [2.0, 0.0, 0.0]'),))
    with pytest.raises(ScenarioError) as caught:
        load_scenario(path)
    message = str(caught.value)
    # the closest pair is named: UH2's slot also moves follower 4's target (0.4 of it), to 0.60 m from it
    assert re.search(r': uhs\[3\]: formation targets of UH2 and UH4 are 0\.60 m apart: closer than two rotor radii '
                     r'\(1\.6 m, the rotor disks overlap\); allowed: >= 1\.6 m$', message), message


def test_initial_positions_closer_than_two_rotor_radii_are_refused_with_the_filter_on(tmp_path):
    replace = (('{position: [1.0, 1.0, 6.0]}', '{position: [2.0, -1.0, 7.0]}'),)
    with pytest.raises(ScenarioError) as caught:
        load_scenario(_paper(tmp_path, 'safety: {enabled: true}\n', replace=replace))
    assert 'initial positions of UH1 and UH4 are 1.00 m apart: closer than two rotor radii' in str(caught.value)


def test_with_the_filter_off_overlapping_places_are_a_warning(tmp_path):
    # the paper's law alone, as published: nothing is refused that loaded before, but the run says so
    replace = (('{position: [1.0, 1.0, 6.0]}', '{position: [2.0, -1.0, 7.0]}'),)
    warnings = load_scenario(_paper(tmp_path, 'safety: {enabled: false}\n', replace=replace)).separation_warnings
    assert [issue.text() for issue in warnings] == ['initial positions of UH1 and UH4 are 1.00 m apart']


def test_targets_inside_the_minimum_separation_are_a_warning(tmp_path):
    # follower 5's target is 1.80 m from follower 4's and from leader 3's slot: a 2 m limit warns of both
    path = _paper(tmp_path, 'safety: {min_separation: 2.0}\n')
    warnings = sorted(issue.text() for issue in load_scenario(path).separation_warnings)
    assert warnings == ['formation targets of UH3 and UH5 are 1.80 m apart',
                        'formation targets of UH4 and UH5 are 1.80 m apart']


def test_the_follower_targets_are_the_containment_combination_of_the_leaders_slots():
    scenario = load_scenario('paper')
    points = formation_points(scenario.leaders, scenario.followers, scenario.offsets, scenario.containment_weights)
    # -L1^-1 L2 = [[0.4, 0.4, 0.2], [0.2, 0.2, 0.6]] (paper.yaml)
    slots = [scenario.offsets[k] for k in (1, 2, 3)]
    assert points[4] == pytest.approx(0.4 * slots[0] + 0.4 * slots[1] + 0.2 * slots[2])
    assert points[5] == pytest.approx(0.2 * slots[0] + 0.2 * slots[1] + 0.6 * slots[2])
    assert sorted((i.first, i.second) for i in close_pairs(points, 1.81, 'formation')) == [(3, 5), (4, 5)]


@pytest.mark.parametrize('value', ['0.0', '-0.8'])
def test_a_rotor_radius_that_is_not_positive_is_refused(tmp_path, value):
    text = AIRFRAME.read_text().replace('rotor_radius: 0.8', f'rotor_radius: {value}')
    path = tmp_path / 'airframe.yaml'
    path.write_text(text)
    with pytest.raises(HelicopterParamsError, match="'rotor_radius' must be > 0"):
        load_helicopter_params(path)


def test_a_scenario_on_its_own_text_gets_the_same_check():
    text = PAPER.read_text().replace('gains: paper_gains.yaml', 'safety: {enabled: true}').replace(
        '{position: [1.0, 1.0, 6.0]}', '{position: [2.5, -1.0, 8.0]}')
    with pytest.raises(ScenarioError, match='initial positions of UH1 and UH4 are 0.50 m apart'):
        parse_scenario(text, source='inline')
