"""What a team run gives its nodes for the scenario: a bundled name as it is, a file by its absolute path."""
from pathlib import Path

import pytest

from uh_bringup import run_formation
from uh_bringup.run_checks import check_run
from uh_topology.scenario import load_scenario


@pytest.mark.parametrize('name', ['square', 'swap', 'crowd'])
def test_a_team_run_passes_a_bundled_scenario_to_its_nodes_by_name(tmp_path, name):
    # the nodes load the scenario themselves: 'square' must not become the path ./square
    args = run_formation.build_parser().parse_args(['--scenario', name, '--out', str(tmp_path / 'run')])
    scenario, scenario_arg, _ = check_run(args)
    assert scenario_arg == name and scenario.name == name
    assert load_scenario(scenario_arg).name == name


def test_a_team_run_passes_a_scenario_file_by_its_absolute_path(tmp_path, monkeypatch):
    source = Path(load_scenario('paper').source)
    (tmp_path / 'mine.yaml').write_text(source.read_text())
    (tmp_path / 'paper_gains.yaml').write_text(load_scenario('paper').gains_path.read_text())
    monkeypatch.chdir(tmp_path)
    args = run_formation.build_parser().parse_args(['--scenario', 'mine.yaml', '--out', str(tmp_path / 'run')])
    _, scenario_arg, _ = check_run(args)
    assert scenario_arg == str(tmp_path / 'mine.yaml')
