"""What the launch file does around the team (uh_bringup.launch_run), without ROS: arguments, steps, metrics.

The launch file's wiring of these decisions into launch actions is tested in tests/test_team_nodes.py;
``ros2 launch`` itself in tests/test_on_ros.py (needs ROS 2).
"""
import json
import shutil
import subprocess
import sys
import time

import pytest
from test_report import shared_team_run

from uh_bringup import launch_run
from uh_bringup.launch_run import ARGUMENTS, LaunchRun, RunFailed, Step, check_arguments

pytestmark = pytest.mark.dds


def _values(tmp_path, **changes):
    values = {name: default for name, default, _ in ARGUMENTS}
    values['out'] = str(tmp_path / 'run')
    values.update(changes)
    return values


def _record(tmp_path):
    return json.loads((tmp_path / 'run' / 'run.json').read_text())


def _launch(tmp_path, **changes):
    """Return the LaunchRun of a launch with these arguments, its run.json written, on a fake clock at 100 s."""
    options = check_arguments(_values(tmp_path, **changes))
    launch_run.write_launch_record(options, 20.0, False, environ={'ROS_DOMAIN_ID': '181'})
    now = [100.0]
    run = LaunchRun(options, 'python3', clock=lambda: now[0])
    return run, now


def test_the_default_arguments_are_the_documented_ones(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)     # the default out is relative: runs/launch_<timestamp>
    options = check_arguments(_values(tmp_path, out=''), now=0)
    assert options.out.name == 'launch_' + time.strftime('%Y%m%d_%H%M%S', time.localtime(0))
    assert (options.clock_mode, options.backend, options.realtime_priority) == ('realtime', 'rclpy', 20)
    assert options.metrics and options.report and options.visualization and options.standard_views
    assert options.duration is None and options.startup_timeout == 60.0
    assert check_arguments(_values(tmp_path, report='False', duration='3')).report is False


@pytest.mark.parametrize('name, value, allowed', [
    ('backend', 'zenoh', 'allowed: rclpy, dds'),
    ('clock_mode', 'fast', 'allowed: lockstep, realtime'),
    ('case', 'case3', 'allowed: proposed, case1, case2'),
    ('realtime_priority', '99', 'allowed an integer 0 (normal scheduling) .. 98'),
    ('report', 'no', 'allowed true or false'),
    ('metrics', 'yes', 'allowed true or false'),
    ('rate', '-1', 'allowed a number > 0'),
    ('duration', 'long', 'allowed a number > 0'),
    ('startup_timeout', 'inf', 'allowed a number > 0'),
    ('safety', 'maybe', "allowed: on, off or empty (the scenario's)"),
])
def test_a_bad_argument_is_one_line_naming_it_and_what_is_allowed(tmp_path, name, value, allowed):
    with pytest.raises(ValueError) as exc:
        check_arguments(_values(tmp_path, **{name: value}))
    assert str(exc.value) == f'launch argument {name}:={value!r}; {allowed}'


def test_safety_on_off_or_the_scenarios_reaches_the_options(tmp_path):
    assert [check_arguments(_values(tmp_path, safety=v)).safety for v in ('on', 'off', '')] == [True, False, None]


def test_an_out_that_cannot_be_written_is_refused(tmp_path):
    (tmp_path / 'file').write_text('')
    with pytest.raises(ValueError, match=r"launch argument out:='.*file/run'; allowed a directory that can be "
                                         r'written \(.*file/run: Not a directory\)'):
        check_arguments(_values(tmp_path, out=str(tmp_path / 'file' / 'run')))


def test_a_complete_run_stops_the_recorder_then_computes_the_metrics_then_ends(tmp_path):
    run, now = _launch(tmp_path, clock_mode='lockstep', report='false')
    assert _record(tmp_path)['exit_status'] is None and _record(tmp_path)['domain_id'] == 181
    assert run.kernels_compiled(0, shutting_down=False) is True
    now[0] += 42.5
    assert run.node_ended('clock', 'clock', 0, shutting_down=False) == Step('stop', 'recorder')
    # the team's other nodes are no longer needed: their ends change nothing
    assert run.node_ended('uh1_sim', 'sim', -9, shutting_down=False) == launch_run.NOTHING
    step = run.node_ended('recorder', 'recorder', 0, shutting_down=False)
    assert step == Step('run', ['python3', '-m', 'uh_bringup.launch_run', str(tmp_path / 'run'), '--wall-time',
                                '42.500', '--no-report'])
    assert run.after_run_ended(0) == Step('shutdown', 'run complete')
    run.launch_shut_down('run complete')     # a completed run's shutdown is not a failure
    with pytest.raises(RunFailed, match=r'the run completed, but its metrics were not written \(status 1'):
        run.after_run_ended(1)


def test_without_metrics_the_recorders_end_ends_the_launch(tmp_path):
    run, _ = _launch(tmp_path, metrics='false')
    run.kernels_compiled(0, shutting_down=False)
    run.node_ended('clock', 'clock', 0, shutting_down=False)
    assert run.node_ended('recorder', 'recorder', 0, shutting_down=False) == Step('shutdown', 'run complete')
    assert _record(tmp_path)['exit_status'] == 0


def test_failed_kernels_start_no_node_and_fail_the_launch(tmp_path):
    run, _ = _launch(tmp_path)
    with pytest.raises(RunFailed, match=r'compiling the kernels .* failed with status 1: .* no node was started'):
        run.kernels_compiled(1, shutting_down=False)
    assert _record(tmp_path)['exit_status'] == 1 and _record(tmp_path)['failed_node'] == 'compile_kernels'
    assert LaunchRun(run.options).kernels_compiled(0, shutting_down=True) is False   # Ctrl-C while compiling


@pytest.mark.parametrize('clock_mode', ['lockstep', 'realtime'])
def test_a_node_that_fails_before_the_end_fails_the_launch(tmp_path, clock_mode):
    run, _ = _launch(tmp_path, clock_mode=clock_mode)
    run.kernels_compiled(0, shutting_down=False)
    with pytest.raises(RunFailed, match='recorder exited with status -9: the run did not complete'):
        run.node_ended('recorder', 'recorder', -9, shutting_down=False)
    assert _record(tmp_path)['exit_status'] == 1 and _record(tmp_path)['failed_node'] == 'recorder'
    assert run.node_ended('recorder', 'recorder', 0, shutting_down=False) == \
        Step('shutdown', 'recorder exited (the run needs its recording)')
    assert run.node_ended('uh2_controller', 'controller', 0, shutting_down=False) == \
        Step('shutdown', 'uh2_controller exited (lockstep needs every node)')
    with pytest.raises(RunFailed, match='clock exited with status 1'):
        run.node_ended('clock', 'clock', 1, shutting_down=False)
    # nodes stopped by the launch's shutdown end quietly; a clock ending then has not completed the run
    assert run.node_ended('clock', 'clock', 0, shutting_down=True) == launch_run.NOTHING
    assert run.node_ended('uh2_sim', 'sim', -15, shutting_down=True) == launch_run.NOTHING
    with pytest.raises(RunFailed, match='every process has ended, and the clock never completed the run'):
        run.launch_shut_down('idle')


def test_an_interrupted_launch_says_so_in_run_json(tmp_path):
    run, _ = _launch(tmp_path)
    run.kernels_compiled(0, shutting_down=False)
    run.launch_shut_down('ctrl-c (SIGINT)', due_to_sigint=True)
    assert _record(tmp_path)['exit_status'] == 130 and _record(tmp_path)['interrupted'] is True


def test_the_after_run_step_writes_what_run_formation_writes(tmp_path_factory, tmp_path):
    """``python -m uh_bringup.launch_run OUT`` on a team's bag: the metrics of run_formation.sh, and the report."""
    team = shared_team_run(tmp_path_factory)
    out = tmp_path / 'run'
    shutil.copytree(team / 'bag', out / 'bag')
    launch_run.write_launch_record(check_arguments(_values(tmp_path, clock_mode='lockstep')), 22.0, False)
    done = subprocess.run([sys.executable, '-P', '-m', 'uh_bringup.launch_run', str(out), '--wall-time', '12.5'],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert '[run] metrics: ' in done.stderr and f'[run] report: {out}/report/index.html' in done.stderr
    metrics, theirs = (json.loads((d / 'metrics.json').read_text()) for d in (out, team))
    assert metrics.pop('wall_time_s') == 12.5
    theirs.pop('wall_time_s')
    assert metrics == theirs
    assert (out / 'report' / 'index.html').stat().st_size > 0
    record = json.loads((out / 'run.json').read_text())
    assert (record['exit_status'], record['wall_time_s'], record['scenario']) == (0, 12.5, 'paper')


def test_the_after_run_step_fails_without_a_bag_and_refuses_a_directory_that_is_not_a_launch(tmp_path, capsys):
    launch_run.write_launch_record(check_arguments(_values(tmp_path)), 20.0, False)
    (tmp_path / 'run' / 'bag').mkdir()
    assert launch_run.main([str(tmp_path / 'run'), '--no-report']) == 1
    assert '[run] metrics: cannot be computed' in capsys.readouterr().err
    record = _record(tmp_path)
    assert record['exit_status'] == 1 and record['metrics_error'] and not (tmp_path / 'run' / 'metrics.json').exists()
    with pytest.raises(SystemExit) as exc:
        launch_run.main([str(tmp_path / 'nothing')])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith('python -m uh_bringup.launch_run: error: ') \
        and 'not the record of a launch' in err
