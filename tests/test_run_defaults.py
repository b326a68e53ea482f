"""The defaults of a team run and the choices of its options have one home (uh_wire.run_defaults).

``scripts/run_formation.sh`` and ``formation.launch.py`` take the startup timeout, the clock modes
and the node backends from there, and no module defines the lists again.
"""
import ast
from pathlib import Path

import pytest

from uh_bringup import launch_run, run_formation
from uh_bringup.launch_run import ARGUMENTS, check_arguments
from uh_runtime import backend
from uh_wire import run_config, run_defaults
from uh_wire.run_defaults import BACKENDS, CLOCK_MODES, DEFAULT_STALE_TIMEOUT, DEFAULT_STARTUP_TIMEOUT

ROOT = Path(__file__).resolve().parents[1]
#: Each name of a run default or choice list, and the one module that may assign it.
HOMES = {
    'BACKENDS': 'uh_runtime/uh_runtime/backend.py',
    'CLOCK_MODES': 'uh_wire/uh_wire/run_config.py',
    'DEFAULT_STALE_TIMEOUT': 'uh_wire/uh_wire/run_config.py',
    'DEFAULT_STARTUP_TIMEOUT': 'uh_wire/uh_wire/run_defaults.py',
}


def _assigned_names(path: Path) -> set:
    """Return the names ``path`` assigns at module level."""
    names = set()
    for node in ast.parse(path.read_text()).body:
        targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(
            node, ast.AnnAssign) else []
        names.update(t.id for t in targets if isinstance(t, ast.Name))
    return names


def test_each_run_default_and_choice_list_is_assigned_in_its_home_only():
    modules = [p for p in sorted(ROOT.glob('uh_*/uh_*/**/*.py')) if '.venv' not in p.parts]
    assert len(modules) > 50
    where = {name: sorted(str(p.relative_to(ROOT)) for p in modules if name in _assigned_names(p)) for name in HOMES}
    assert where == {name: [home] for name, home in HOMES.items()}


def test_the_one_home_gives_the_definitions_themselves():
    assert run_defaults.BACKENDS is backend.BACKENDS == ('rclpy', 'dds')
    assert run_defaults.CLOCK_MODES is run_config.CLOCK_MODES == ('lockstep', 'realtime')
    assert DEFAULT_STALE_TIMEOUT is run_config.DEFAULT_STALE_TIMEOUT
    assert DEFAULT_STARTUP_TIMEOUT == 60.0


def test_the_run_command_takes_its_defaults_and_clock_modes_from_the_home():
    parser = run_formation.build_parser()
    args = parser.parse_args([])
    assert args.startup_timeout == DEFAULT_STARTUP_TIMEOUT and args.stale_timeout == DEFAULT_STALE_TIMEOUT
    clock = next(a for a in parser._actions if '--clock' in a.option_strings)
    assert tuple(clock.choices) == CLOCK_MODES


def test_the_launch_takes_its_defaults_and_choices_from_the_home(tmp_path):
    defaults = {name: default for name, default, _ in ARGUMENTS}
    assert float(defaults['startup_timeout']) == DEFAULT_STARTUP_TIMEOUT
    assert float(defaults['stale_timeout']) == DEFAULT_STALE_TIMEOUT
    assert launch_run.BACKENDS is BACKENDS and launch_run.CLOCK_MODES is CLOCK_MODES
    values = dict(defaults, out=str(tmp_path / 'run'))
    assert check_arguments(values).startup_timeout == DEFAULT_STARTUP_TIMEOUT
    for name, allowed in (('backend', BACKENDS), ('clock_mode', CLOCK_MODES)):
        with pytest.raises(ValueError, match=f'allowed: {", ".join(allowed)}$'):
            check_arguments(dict(values, **{name: 'other'}))
