"""The ROS-free helpers of the simulator and controller nodes.

:class:`uh_sim_node.command_watch.CommandWatch` (late and stale commands, the simulator's
diagnostics window) and :class:`uh_controller_node.controller_diagnostics.ControllerDiagnostics`
(the controller's diagnostics window and when it reports); no DDS, log lines go to a list.
"""
import types

import numpy as np
from fake_wall import RecordingLogger

from uh_controller_node.controller_diagnostics import ControllerDiagnostics
from uh_controller_node.input_sync import REFERENCE, LagStats, StepInputs
from uh_core import diagnostics as D
from uh_sim_node.command_watch import CommandWatch


def test_command_watch_counts_late_commands_and_reports_a_stale_one_once():
    logger = RecordingLogger()
    watch = CommandWatch(uh_id=2, dt=0.01, stale_steps=3, logger=logger)
    watch.integrating(0)                 # step 0 before any command: not late
    watch.taken(0, 0)
    watch.integrating(0)
    assert watch.late_commands == 0 and logger.lines == []
    for step in range(1, 6):
        watch.integrating(step)
    assert watch.late_commands == 5 and watch.command_stale
    assert logger.texts('warning') == [
        'step 1 integrated with the command of step 0 (1 late command(s) so far)',
        'no command since step 0 (plant at step 4, timeout 0.03 s): holding it; is /uh2/controller running?']
    watch.taken(6, 6)
    assert not watch.command_stale
    assert logger.texts('info') == ['commands arrive again (step 6, plant at step 6)']


def test_command_watch_windows_count_since_the_previous_report():
    watch = CommandWatch(uh_id=1, dt=0.01, stale_steps=25, logger=RecordingLogger())
    watch.rejected, watch.rejected_faults = 2, 1
    first = watch.window(10, (False,) * 4, (False,) * 4)
    assert (first.last_step, first.rejected_commands, first.rejected_faults, first.late_commands) == (10, 2, 1, 0)
    watch.rejected += 3
    second = watch.window(20, (True, False, False, False), (False,) * 4)
    assert (second.rejected_commands, second.rejected_faults, second.fault_active[0]) == (3, 0, True)
    assert isinstance(second, D.SimulatorWindow)


def _status(saturated=False):
    return types.SimpleNamespace(
        saturated_tilt=saturated, saturated_collective=False, saturated_cyclic=False,
        safety_active=False, closest_distance=float('nan'),
        isolation=types.SimpleNamespace(isolated=(False, True, False, False)),
        fault_estimate_position=np.array([3.0, 4.0, 0.0]), fault_estimate_attitude=np.zeros(3))


def test_controller_diagnostics_report_at_the_phase_with_the_windows_counts():
    diag = ControllerDiagnostics(uh_id=4, every=5, phase=2)
    sync = types.SimpleNamespace(lag={1: LagStats(last=3)}, rejected={'state of uh1': 2})
    reports = []
    for k in range(8):
        inputs = StepInputs(k, np.zeros(12), {}, None, stale=(REFERENCE,) if k == 7 else ())
        if k == 1:
            diag.not_computed()
            continue
        reports.append((k, diag.add(k, inputs, _status(saturated=k == 0), sync)))
    due = [(k, r) for k, r in reports if r is not None]
    assert [k for k, _ in due] == [2, 7]
    first = due[0][1]
    assert first.name == 'uh4/controller' and first.level == D.ERROR
    assert first.values['steps in window'] == '2' and first.values['saturated steps'] == '1'
    assert first.values['rejected inputs'] == '2' and first.values['max input lag (steps)'] == '3'
    assert first.values['steps not computed'] == '1' and first.values['|Fhat_p| (m/s^2)'] == '5'
    second = due[1][1]
    assert second.values['rejected inputs'] == '0' and second.values['stale inputs'] == 'reference'
    assert second.values['steps not computed'] == '0' and second.values['steps in window'] == '5'
