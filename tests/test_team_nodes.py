"""One table of nodes (uh_bringup.team_nodes) behind everything that starts nodes.

The entry points, the composition, the run script and the launch file all use it, so they cannot drift apart.
"""
import ast
import importlib
import json
import runpy
import sys
import types
from pathlib import Path

import pytest

from uh_bringup import run_formation
from uh_bringup.launch_run import RunFailed
from uh_bringup.run_processes import processes, worker_groups
from uh_bringup.team_nodes import NODES, node_class, node_specs
from uh_topology.scenario import load_scenario
from uh_wire.run_config import DEFAULT_STALE_TIMEOUT

ROOT = Path(__file__).resolve().parents[1]


def _console_scripts(pkg: str) -> dict:
    """Return ``{executable: 'module:function'}`` of a package's setup.py."""
    tree = ast.parse((ROOT / pkg / 'setup.py').read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Dict):
            for key, value in zip(node.keys, node.values, strict=True):
                if isinstance(key, ast.Constant) and key.value == 'console_scripts':
                    entries = [ast.literal_eval(e) for e in value.elts]
                    return dict((part.strip() for part in e.split('=')) for e in entries)
    return {}


@pytest.mark.parametrize('kind', sorted(NODES))
def test_every_node_kind_has_its_entry_point_and_class(kind):
    spec = NODES[kind]
    assert _console_scripts(spec.package).get(spec.executable) == spec.entry_point
    cls = node_class(kind)
    module, function = spec.entry_point.split(':')
    assert isinstance(cls, type) and callable(getattr(importlib.import_module(module), function))
    assert callable(importlib.import_module(spec.module).main)


def test_unknown_node_kind_is_refused_with_the_allowed_ones():
    with pytest.raises(ValueError, match="unknown node kind 'radar'; allowed: recorder, sim, controller"):
        node_class('radar')


def test_per_node_processes_start_the_entry_points_of_the_table(tmp_path):
    scenario = load_scenario('paper')
    specs = node_specs(scenario, 'paper', 'proposed', 'lockstep', 1.0, None, tmp_path / 'bag', 60.0)
    commands = run_formation.process_commands(specs, 'per-node', tmp_path)
    for (name, kind, args), (proc_name, cmd) in zip(specs, commands, strict=False):
        assert proc_name == name
        assert Path(cmd[0]).name == NODES[kind].executable and cmd[1:] == args
    kinds = [kind for _, kind, _ in specs]
    assert kinds[0] == 'recorder' and kinds[-1] == 'clock'
    assert kinds.count('sim') == kinds.count('controller') == len(scenario.ids)
    assert 'visualization' in kinds


@pytest.mark.parametrize('ids, workers, expected', [
    ((1, 2, 3, 4, 5), 2, {1: 'uh1-2', 2: 'uh1-2', 3: 'uh3-5', 4: 'uh3-5', 5: 'uh3-5'}),
    ((3, 1, 2), 5, {1: 'uh1', 2: 'uh2', 3: 'uh3'}),          # at most one worker per UH
    ((7, 8), 1, {7: 'uh7-8', 8: 'uh7-8'}),
])
def test_workers_hold_blocks_of_consecutive_uhs_as_even_as_can_be(ids, workers, expected):
    assert worker_groups(ids, workers) == expected


def test_the_workers_layout_puts_each_uhs_nodes_in_its_block_and_the_team_and_recorder_apart(tmp_path):
    scenario = load_scenario('paper')    # UHs 1..5
    specs = node_specs(scenario, 'paper', 'proposed', 'lockstep', 1.0, None, tmp_path / 'bag', 60.0)
    started = processes(specs, 'workers', tmp_path, workers=2)
    assert [(name, kind) for name, kind, _cmd in started] == [
        ('recorder', 'recorder'), ('uh1-2', 'sim'), ('uh3-5', 'sim'), ('team', 'clock')]   # the clock's last
    nodes = {name: [n['name'] for n in json.loads((tmp_path / f'{name}.nodes.json').read_text())]
             for name, _kind, _cmd in started}
    assert nodes['uh1-2'] == ['uh1_sim', 'uh1_controller', 'uh2_sim', 'uh2_controller']
    assert sorted(nodes['uh3-5']) == sorted(f'uh{i}_{k}' for i in (3, 4, 5) for k in ('sim', 'controller'))
    assert 'clock' in nodes['team'] and 'virtual_leader' in nodes['team']
    assert all(cmd[-3:-1] == ['-m', 'uh_bringup.composed'] for _name, _kind, cmd in started)


class _Recorder:
    """Stands in for a launch class: keeps its constructor arguments."""

    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


def _fake_launch_modules(monkeypatch):
    """Install minimal ``launch`` and ``launch_ros`` modules (ROS 2 is not installed here).

    Each class records how it was built, so the launch file's own logic runs.
    """
    mods = {name: types.ModuleType(name) for name in
            ('launch', 'launch.actions', 'launch.event_handlers', 'launch.events', 'launch.events.process',
             'launch.substitutions', 'launch_ros', 'launch_ros.actions')}
    classes = {'launch': ['LaunchDescription'],
               'launch.actions': ['DeclareLaunchArgument', 'EmitEvent', 'ExecuteProcess', 'LogInfo', 'OpaqueFunction',
                                  'RegisterEventHandler'],
               'launch.event_handlers': ['OnProcessExit', 'OnShutdown'], 'launch.events': ['Shutdown'],
               'launch.events.process': ['ShutdownProcess'],
               'launch.substitutions': ['LaunchConfiguration'], 'launch_ros.actions': ['Node']}
    for mod, names in classes.items():
        for name in names:
            setattr(mods[mod], name, type(name, (_Recorder,), {}))
    mods['launch.events'].matches_action = lambda action: ('matches', action)
    for name, mod in mods.items():
        monkeypatch.setitem(sys.modules, name, mod)
    return mods


def _registered(actions, mods, kind):
    return [a.args[0] for a in actions
            if isinstance(a, mods['launch.actions'].RegisterEventHandler)
            and isinstance(a.args[0], getattr(mods['launch.event_handlers'], kind))]


#: Launch contexts: the launch running, and shutting down (its own shutdown stops the nodes).
_RUNNING, _STOPPING = types.SimpleNamespace(is_shutdown=False), types.SimpleNamespace(is_shutdown=True)


class _LaunchFile:
    """formation.launch.py run on the fake launch modules, its arguments at their defaults (lockstep, into tmp_path)."""

    def __init__(self, monkeypatch, tmp_path):
        self.mods = _fake_launch_modules(monkeypatch)
        launch_file = runpy.run_path(str(ROOT / 'uh_bringup' / 'launch' / 'formation.launch.py'))
        description = launch_file['generate_launch_description']()
        self.arguments = {a.args[0]: a.kwargs['default_value'] for a in description.args[0]
                          if isinstance(a, self.mods['launch.actions'].DeclareLaunchArgument)}
        self.arguments.update(clock_mode='lockstep', out=str(tmp_path))
        self.opaque = description.args[0][-1]
        arguments = self.arguments
        self.mods['launch.substitutions'].LaunchConfiguration.perform = (
            lambda configuration, context: arguments[configuration.args[0]])

    def actions(self):
        """Return the actions the launch file's opaque function gives with the current arguments."""
        return self.opaque.kwargs['function'](None)

    def registered(self, actions, kind):
        """Return the event handlers of type ``kind`` that ``actions`` register."""
        return _registered(actions, self.mods, kind)

    def nodes(self, actions):
        """Return the ROS nodes among ``actions``."""
        return [a for a in actions if isinstance(a, self.mods['launch_ros.actions'].Node)]

    def started(self, actions):
        """Return the team's actions, once the kernel compilation (the launch's first process) ended with status 0."""
        [compiling] = [a for a in actions if isinstance(a, self.mods['launch.actions'].ExecuteProcess)]
        assert compiling.kwargs['cmd'] == [sys.executable, '-m', 'uh_team.compile_kernels']
        [compiled] = self.registered(actions, 'OnProcessExit')
        assert compiled.kwargs['target_action'] is compiling
        assert not self.nodes(actions)   # not before it
        return compiled.kwargs['on_exit'](types.SimpleNamespace(returncode=0), _RUNNING)


@pytest.fixture
def launch(monkeypatch, tmp_path):
    return _LaunchFile(monkeypatch, tmp_path)


def _outcome(handler, status, context=_RUNNING):
    """Return what an exit handler does when its process ends with ``status`` (``'failed: ...'`` if it raises)."""
    try:
        return handler.kwargs['on_exit'](types.SimpleNamespace(returncode=status), context)
    except RunFailed as exc:
        return f'failed: {exc}'


def _reasons(done):
    return [a.kwargs['event'].kwargs['reason'] for a in done]


def _ends(handler, reason):
    """Return what a shutdown handler does when the launch ends for ``reason`` (``'failed: ...'`` if it raises)."""
    try:
        return handler.kwargs['on_shutdown'](types.SimpleNamespace(reason=reason, due_to_sigint='ctrl-c' in reason),
                                             _STOPPING)
    except RunFailed as exc:
        return f'failed: {exc}'


def test_launch_file_starts_the_run_scripts_nodes_and_ends_with_the_clock(launch, tmp_path):
    """The launch file compiles the kernels, then starts node_specs' nodes; the clock's end leads to the metrics.

    The decisions themselves are tested in tests/test_launch_run.py; here, that the launch file wires them.
    """
    team = launch.started(launch.actions())
    assert json.loads((tmp_path / 'run.json').read_text())['scenario'] == 'paper'   # what uh-report OUT reads
    nodes = launch.nodes(team)
    expected = node_specs(load_scenario('paper'), 'paper', launch.arguments['case'], 'lockstep', 1.0, None,
                          f'{tmp_path}/bag', 60.0, DEFAULT_STALE_TIMEOUT)
    assert [(n.kwargs['package'], n.kwargs['executable'], n.kwargs['arguments']) for n in nodes] == \
        [(NODES[kind].package, NODES[kind].executable, args) for _, kind, args in expected]
    handlers = launch.registered(team, 'OnProcessExit')
    # lockstep: the death of any node ends the launch
    assert [h.kwargs['target_action'] for h in handlers] == nodes
    assert _reasons(_outcome(handlers[0], 0))[0].endswith('(the run needs its recording)')
    assert _reasons(_outcome(handlers[1], 0))[0].endswith('(lockstep needs every node)')
    assert _outcome(handlers[1], -9).startswith('failed: uh1_sim exited with status -9')
    assert _outcome(handlers[-1], 1).startswith('failed: clock exited with status 1')
    # nodes stopped by the launch's own shutdown end quietly, whatever their status
    assert _outcome(handlers[1], -2, _STOPPING) == [] and _outcome(handlers[-1], 1, _STOPPING) == []
    # the clock completes the run: the recorder is stopped (it finalises the bag), then the metrics are computed
    [stop] = _outcome(handlers[-1], 0)
    assert stop.kwargs['event'].kwargs['process_matcher'] == ('matches', nodes[0])
    assert _outcome(handlers[1], -9) == []      # after the completion no node is needed
    after_run, on_after_run = _outcome(handlers[0], -2)
    assert after_run.kwargs['cmd'][:4] == [sys.executable, '-m', 'uh_bringup.launch_run', str(tmp_path)]
    assert on_after_run.args[0].kwargs['target_action'] is after_run
    assert _reasons(_outcome(on_after_run.args[0], 0)) == ['run complete']
    assert _outcome(on_after_run.args[0], 1).startswith('failed: the run completed, but its metrics were not written')


def test_a_launch_that_ends_idle_failed_unless_its_clock_completed_the_run(launch):
    """No node could even start (launch sends no exit event): failed; Ctrl-C is not a failure of the run."""
    actions = launch.actions()
    [idle] = launch.registered(actions, 'OnShutdown')
    team = launch.started(actions)
    [_stop] = _outcome(launch.registered(team, 'OnProcessExit')[-1], 0)   # the clock completes the run
    [fresh_idle] = launch.registered(launch.actions(), 'OnShutdown')
    assert _ends(fresh_idle, 'idle').startswith('failed: every process has ended, and the clock never completed')
    assert _ends(fresh_idle, 'ctrl-c (SIGINT)') is None
    assert _ends(idle, 'idle') is None   # this launch's clock completed above


def test_launch_file_in_real_time_gives_the_control_loop_its_priority(launch):
    launch.arguments.update(clock_mode='realtime', visualization='false')
    team = launch.started(launch.actions())
    handlers = launch.registered(team, 'OnProcessExit')
    assert [h.kwargs['target_action'].kwargs['executable'] for h in handlers] == ['recorder_node',
                                                                                  'lockstep_clock_node']
    # realtime: the control loop's nodes get the SCHED_FIFO priority (default 20), the recorder not
    priority = {n.kwargs['executable']: [a for a in n.kwargs['arguments'] if a.startswith('realtime_priority:=')]
                for n in launch.nodes(team)}
    assert priority.pop('recorder_node') == []
    assert set(map(tuple, priority.values())) == {('realtime_priority:=20',)}
    for bad in ('99', '-1', 'high'):
        launch.arguments['realtime_priority'] = bad
        with pytest.raises(ValueError, match=f"realtime_priority:='{bad}'; allowed an integer 0"):
            launch.actions()
    launch.arguments['realtime_priority'] = '20'
    assert 'visualization_node' not in [a.kwargs.get('executable') for a in team]


def test_launch_file_backend_argument_chooses_the_nodes_backend(launch):
    launch.arguments.update(clock_mode='realtime', visualization='false')
    # backend:=dds puts every node on the DDS backend; by default only the infrastructure may be
    nodes = launch.nodes(launch.started(launch.actions()))
    assert all(n.kwargs['additional_env'].get('UH_BACKEND') != 'dds' for n in nodes
               if n.kwargs['executable'] in ('sim_node', 'controller_node'))
    launch.arguments.update(backend='dds')
    nodes = launch.nodes(launch.started(launch.actions()))
    assert nodes and all(n.kwargs['additional_env']['UH_BACKEND'] == 'dds' for n in nodes)
    # and every node the runs' discovery settings, which rclpy on Fast DDS and Cyclone DDS meet on
    assert all(n.kwargs['additional_env'].get('ROS_AUTOMATIC_DISCOVERY_RANGE') for n in nodes)
    launch.arguments.update(backend='zenoh')
    with pytest.raises(ValueError, match="backend:='zenoh'; allowed: rclpy, dds"):
        launch.actions()
