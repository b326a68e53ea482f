"""The compiled fault isolator gives the same bits as the pure-Python one it replaced.

``tests/isolation_oracle.py`` is a frozen copy of the Python isolator. On the paper scenario's runs
(all three cases), on runs with random faults and on random synthetic inputs, the compiled isolator
must give exactly its numbers, with no tolerance (the kernels keep IEEE double arithmetic and the
same order of operations): at every step the filtered deviations, thresholds, deviations and the
published status (verdicts, detection times, identified rho and b), online (:meth:`FaultIsolator.update`
step by step) and offline (:meth:`FaultIsolator.run`, :func:`isolate_run`, every step in one
compiled call); at the end every channel's report.
"""
import dataclasses
import struct
from pathlib import Path

import isolation_oracle as oracle
import numpy as np
import pytest
import yaml

from uh_controller_node import fault_isolation as fi
from uh_controller_node import isolation_kernels as kernels
from uh_controller_node import isolation_runs
from uh_controller_node.nominal_model import nominal_model
from uh_core.airframe import load_helicopter_params

CHANNEL_NAMES = ('collective', 'tail_rotor', 'lateral', 'longitudinal')


def same(a, b, where='') -> None:
    """Assert that ``a`` and ``b`` are the same, floats to the bit (NaN included), recursively."""
    if isinstance(a, float) or isinstance(b, float):
        assert isinstance(a, float) and isinstance(b, float), (where, a, b)
        assert struct.pack('<d', a) == struct.pack('<d', b), (where, a, b)
    elif isinstance(a, dict):
        assert isinstance(b, dict) and list(a) == list(b), (where, list(a), b)
        for key in a:
            same(a[key], b[key], f'{where}.{key}')
    elif isinstance(a, (tuple, list)):
        assert type(a) is type(b) and len(a) == len(b), (where, a, b)
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            same(x, y, f'{where}[{i}]')
    else:
        assert type(a) is type(b) and a == b, (where, a, b)


def same_array(a, b, where='') -> None:
    """Assert two float arrays are equal to the bit."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    assert a.shape == b.shape, (where, a.shape, b.shape)
    diff = np.flatnonzero(a.view(np.uint64).ravel() != b.view(np.uint64).ravel())
    first = int(diff[0]) if diff.size else None
    assert first is None, (where, 'first difference at flat index', first, a.ravel()[first], b.ravel()[first])


def status_fields(status) -> tuple:
    """Return the fields of an IsolationStatus (the oracle's or the module's) as a plain tuple."""
    return tuple(status)


def compare_one_uh(nominal, mismatch, dt, o_settings, steps) -> bool:
    """Run the oracle and the compiled isolator over ``steps`` (rows of update's arguments); assert they agree.

    Returns whether some channel was isolated (so the comparison covered the fits and verdicts).
    """
    settings = fi.IsolationSettings(**dataclasses.asdict(o_settings))
    old = oracle.FaultIsolator(nominal, mismatch, dt, o_settings)
    new = fi.FaultIsolator(nominal, mismatch, dt, settings)
    expected_trace = []
    for k, (t, x, u, fp, fw) in enumerate(steps):
        old.update(t, x, u, fp, fw)
        new.update(t, x, u, fp, fw)
        expected_trace.append(old.filtered_deviation + old.threshold + old.deviation)
        same(status_fields(new.status()), status_fields(old.status()), f'status at row {k}')
    same(new.filtered_deviation + new.threshold + new.deviation, expected_trace[-1], 'last step')
    # offline: every step in one compiled call, traced
    columns = [np.array([step[i] for step in steps], dtype=float) for i in range(5)]
    offline = fi.FaultIsolator(nominal, mismatch, dt, settings)
    trace = np.empty((len(steps), kernels.TRACE_COLUMNS))
    offline.run(*columns, trace=trace)
    same_array(trace, np.array(expected_trace), 'offline trace')
    for c in range(4):
        expected = dataclasses.astuple(old.channel(c))
        same(dataclasses.astuple(new.channel(c)), expected, f'online report {c}')
        same(dataclasses.astuple(offline.channel(c)), expected, f'offline report {c}')
    same(status_fields(offline.status()), status_fields(old.status()), 'offline status')
    return any(old.isolated)


def compare_run(scenario, case, arrays) -> int:
    """Compare the isolators over a team run per UH and isolate_run; return how many UHs had an isolation."""
    nominal, o_settings, data = oracle._setup(arrays, scenario, case, None)
    isolating = 0
    for j in range(len(tuple(scenario.ids))):
        steps = list(oracle._steps(data, j))
        isolating += compare_one_uh(nominal, scenario.model_mismatch, float(scenario.dt), o_settings, steps)
    same(isolation_runs.isolate_run(arrays, scenario, case), oracle.isolate_run(arrays, scenario, case), 'isolate_run')
    return isolating


@pytest.mark.parametrize('case', ['proposed', 'case1', 'case2'])
def test_the_paper_runs_isolation_is_the_pure_python_isolators_to_the_bit(case):
    from uh_team.team_simulation import run_team_simulation
    from uh_topology.scenario import load_scenario

    scenario = load_scenario('paper')
    arrays = run_team_simulation(scenario, case).arrays()
    assert compare_run(scenario, case, arrays) >= 1   # the paper's faults are isolated: fits and verdicts compared


def random_faults(rng, ids, count) -> list:
    """``count`` faults on random UHs and channels (constant or sinusoidal bias), onsets 9-25 s."""
    faults = []
    for _ in range(count):
        fault = {'uh': int(rng.choice(ids)), 'channel': CHANNEL_NAMES[int(rng.integers(4))],
                 'rho': round(float(rng.uniform(0.6, 1.0)), 3), 'onset_time': round(float(rng.uniform(9.0, 25.0)), 2)}
        if rng.random() < 0.5:
            fault['bias_constant'] = round(float(rng.uniform(-0.01, 0.01)), 4)
        else:
            fault.update(bias_amplitude=round(float(rng.uniform(0.0, 0.01)), 4),
                         bias_frequency=round(float(rng.uniform(0.1, 1.0)), 2))
        faults.append(fault)
    return faults


@pytest.mark.parametrize('base, seed', [('paper', 1), ('paper', 2), ('square', 3)])
def test_runs_with_random_faults_isolate_as_the_pure_python_isolator_to_the_bit(tmp_path, base, seed):
    """Random faults on the paper scenario, and on the square team circling without turning its nose.

    The square team's manoeuvre sweeps the cyclics, so some fits there are identifiable
    (test_fault_isolation.test_a_manoeuvring_team_gets_its_constant_faults_identified).
    """
    from uh_team.team_simulation import run_team_simulation
    from uh_topology.scenario import load_scenario

    rng = np.random.default_rng(seed)
    scenario = load_scenario(base)
    data = yaml.safe_load(open(scenario.source).read())
    data['name'] = f'{base}_random_faults_{seed}'
    data['gains'] = str((Path(scenario.source).parent / data['gains']).resolve())
    data['duration'] = 30.0
    if base == 'square':
        data['reference'].update(angular_rate=0.3, yaw_rate=0.0)
    data['faults'] = random_faults(rng, list(scenario.ids), 4)
    path = tmp_path / f'{data["name"]}.yaml'
    path.write_text(yaml.safe_dump(data))
    scenario = load_scenario(path)
    assert compare_run(scenario, 'proposed', run_team_simulation(scenario, 'proposed').arrays()) >= 1


@pytest.mark.parametrize('forgetting, nan_row', [(1.0, None), (0.98, None), (1.0, 150)])
def test_random_inputs_give_the_pure_python_isolators_bits(forgetting, nan_row):
    """Arbitrary states, commands beyond the limits and noisy estimates, low thresholds: every channel isolates.

    With a NaN estimate in one row (``nan_row``), the NaN propagates the same way (the window's max and min,
    the filters and the fits are Python's, NaN included).
    """
    rng = np.random.default_rng(7)
    nominal = nominal_model(load_helicopter_params(), 0.9)
    rows, dt = 600, 0.01
    lower, upper = np.asarray(nominal.input_lower, dtype=float), np.asarray(nominal.input_upper, dtype=float)
    times = np.arange(rows) * dt
    states = rng.normal(0.0, 0.3, (rows, 12))
    commands = rng.uniform(lower - 0.1 * (upper - lower), upper + 0.1 * (upper - lower), (rows, 4))
    fault_p, fault_w = rng.normal(0.0, 0.5, (rows, 3)), rng.normal(0.0, 0.5, (rows, 3))
    if nan_row is not None:
        fault_p[nan_row, 2] = np.nan
    settings = oracle.IsolationSettings(learning_phase=0.5, thresholds=(1e-5,) * 4, confirmation_time=0.05,
                                        forgetting=forgetting, min_fit_time=0.5)
    steps = [(float(times[k]), states[k], commands[k], fault_p[k], fault_w[k]) for k in range(rows)]
    assert compare_one_uh(nominal, 0.9, dt, settings, steps)


def test_the_deviation_map_is_the_pure_python_one_to_the_bit():
    rng = np.random.default_rng(11)
    nominal = nominal_model(load_helicopter_params(), 0.9)
    for _ in range(200):
        x, u = rng.normal(0.0, 0.5, 12), rng.normal(0.0, 0.1, 4)
        fp, fw = rng.normal(0.0, 1.0, 3), rng.normal(0.0, 1.0, 3)
        d, dT = fi.input_deviation(nominal, x, u, fp, fw)
        d_old, dT_old = oracle.input_deviation(nominal, x, u, fp, fw)
        same_array(d, d_old, 'd')
        same(dT, dT_old, 'dT')


def test_the_kernels_verdict_codes_are_the_modules():
    assert (kernels._FIT_TOO_SHORT, kernels._BIAS_NOT_CONSTANT, kernels._CONFOUNDED, kernels._IDENTIFIABLE) == (
        fi.FIT_TOO_SHORT, fi.BIAS_NOT_CONSTANT, fi.CONFOUNDED, fi.IDENTIFIABLE)


def test_a_trace_of_the_wrong_shape_is_rejected():
    iso = fi.FaultIsolator(nominal_model(load_helicopter_params(), 0.9), 0.9, 0.01)
    with pytest.raises(ValueError, match='trace must be'):
        iso.run(np.zeros(3), np.zeros((3, 12)), np.zeros((3, 4)), np.zeros((3, 3)), np.zeros((3, 3)),
                trace=np.zeros((2, kernels.TRACE_COLUMNS)))


USE_EVERY_KERNEL = """
import json
import numpy as np
from uh_controller_node import fault_isolation as fi, isolation_kernels as kernels, isolation_runs
from uh_controller_node.nominal_model import nominal_model
from uh_core.airframe import load_helicopter_params
from uh_team.team_simulation import run_team_simulation
from uh_topology.scenario import load_scenario

public = [kernels.isolation_step, kernels.isolation_run, kernels.isolation_verdict, kernels.isolation_status,
          kernels.input_deviations]
kernels.compile_isolation_kernels()
compiled = {d.py_func.__name__: len(d.signatures) for d in public}
scenario = load_scenario('paper')
arrays = run_team_simulation(scenario, 'proposed', duration=11.0).arrays()   # past the 10 s onsets
isolated = sum(len(isolation_runs.isolate_run(arrays, scenario)[f'uh{uh}']['isolated']) for uh in scenario.ids)
nominal = nominal_model(load_helicopter_params(), scenario.model_mismatch)
iso = fi.FaultIsolator(nominal, scenario.model_mismatch, float(scenario.dt))
for k in range(arrays['time'].shape[0]):
    iso.update(k * float(scenario.dt), arrays['states'][k, 1], arrays['commands'][k, 1], arrays['fault_est_p'][k, 1],
               arrays['fault_est_w'][k, 1])
    iso.status()
iso.report()
fi.input_deviation(nominal, arrays['states'][0, 0], arrays['commands'][0, 0], np.zeros(3), np.zeros(3))
used = {d.py_func.__name__: len(d.signatures) for d in public}
print(json.dumps({'compiled': compiled, 'used': used, 'isolated': isolated, 'uh2_isolated': sum(iso.isolated)}))
"""


def test_the_install_scripts_compile_every_signature_the_isolator_uses():
    """compile_isolation_kernels (run by uh_team.compile_kernels) compiles what the isolator calls, nothing more later.

    In a fresh process: after it, online (update, status, report), offline (isolate_run) and input_deviation add no
    signature to any kernel, so a process that loads the cache compiles nothing.
    """
    import json
    import subprocess
    import sys

    from uh_core import kernel_cache

    done = subprocess.run([sys.executable, '-P', '-c', USE_EVERY_KERNEL], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out['isolated'] > 0 and out['uh2_isolated'] > 0     # the paper's faults: fits and verdicts were used
    assert out['compiled'] == out['used'] == {name: 1 for name in out['compiled']}, out
    # the kernels read uh_core/layout.py: their cache is flushed when it changes (marker written on import)
    assert kernels.isolation_step in kernel_cache.module_dispatchers(vars(kernels))
    marker = Path(kernels.isolation_step._cache.cache_path) / 'isolation_kernels.dependencies.sha256'
    assert marker.is_file()
