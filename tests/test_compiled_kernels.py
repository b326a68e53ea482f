"""Kernels compiled ahead of time (uh_core.compiled_kernels, docs/performance.md#memory).

The node processes run the model, the law and the fault isolator from one extension module built
from the numba kernels, without importing numba. These tests check that such a process gives the
same numbers to the bit as numba's JIT, that it holds no numba, and that a wrong or unbuilt form
is refused with a clear error. The full 60 s team run of nodes on compiled kernels against the
numba team loop is ``tests/test_distributed_run.py::test_bag_trajectories_equal_the_in_process_reference``.
"""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scenario_texts import paper_yaml

from uh_core import compiled_kernels
from uh_team.team_simulation import run_team_simulation
from uh_topology.scenario import load_scenario

DATA = Path(__file__).parent / 'data'

# the object loop (what the nodes run) in a fresh process, its arrays saved for the test to compare
OBJECT_LOOP = '''
import sys
import numpy as np
from uh_core import compiled_kernels
from uh_team.team_simulation import run_team_simulation
from uh_topology.scenario import load_scenario
run = run_team_simulation(load_scenario(sys.argv[1]), 'proposed', duration=float(sys.argv[2]), engine='objects')
np.savez(sys.argv[3], **run.arrays())
# VmHWM, not ru_maxrss: Linux carries ru_maxrss over from the forking parent (pytest) across exec
peak_mb = [int(line.split()[1]) // 1024 for line in open('/proc/self/status') if line.startswith('VmHWM')][0]
print(compiled_kernels.kernel_form().split()[0], 'numba' in sys.modules, peak_mb)
'''


def _env(**values) -> dict:
    env = dict(os.environ)
    env.pop(compiled_kernels.MODE_VARIABLE, None)
    env.pop(compiled_kernels.DIR_VARIABLE, None)
    env.update(values)
    return env


def _python(code: str, *args, **env) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-P', '-c', code, *map(str, args)], env=_env(**env),
                          capture_output=True, text=True, timeout=300)


@pytest.fixture(scope='module')
def built():
    """Return the compiled module for these sources (built by scripts/_venv.sh, or here after a kernel edit)."""
    if compiled_kernels.find_built() is None:
        subprocess.run([sys.executable, '-P', '-m', 'uh_team.compile_kernels'], check=True, env=_env(),
                       capture_output=True, timeout=600)
    path = compiled_kernels.find_built()
    assert path is not None
    return path


@pytest.mark.parametrize('scenario', ['paper', 'impaired'])
def test_the_object_loop_on_compiled_kernels_equals_numba_to_the_bit(built, tmp_path, scenario):
    if scenario == 'impaired':   # every impairment: noise, loss, delays with jitter and prediction, dropouts
        text = (DATA / 'paper_impaired.yaml').read_text().replace(
            '  delay_steps: 3\n', '  delay_steps: 3\n  jitter_steps: 4\n  delay_compensation: predict\n')
        scenario = tmp_path / 'impaired.yaml'
        scenario.write_text(paper_yaml(text))
    # 12 s: through the paper's fault onset at t = 10 s, so the faulted model and the isolator run
    result = _python(OBJECT_LOOP, scenario, 12.0, tmp_path / 'compiled.npz', UH_KERNELS='compiled')
    assert result.returncode == 0, result.stderr
    form, numba_loaded, _rss_mb = result.stdout.split()
    assert (form, numba_loaded) == ('compiled', 'False'), result.stdout
    compiled = np.load(tmp_path / 'compiled.npz')
    reference = run_team_simulation(load_scenario(str(scenario)), 'proposed', duration=12.0, engine='objects').arrays()
    for key, value in reference.items():
        assert np.array_equal(compiled[key], value), key
    assert np.abs(reference['fault_true_p'][-1]).max() > 0.0   # the faults acted in the compared span


def test_a_process_on_compiled_kernels_holds_far_less_memory_than_on_numba(built, tmp_path):
    compiled = _python(OBJECT_LOOP, 'paper', 1.0, tmp_path / 'a.npz', UH_KERNELS='compiled')
    jit = _python(OBJECT_LOOP, 'paper', 1.0, tmp_path / 'b.npz', UH_KERNELS='numba')
    assert compiled.returncode == 0 and jit.returncode == 0, compiled.stderr + jit.stderr
    compiled_form, _, compiled_mb = compiled.stdout.split()
    jit_form, jit_numba, jit_mb = jit.stdout.split()
    assert (compiled_form, jit_form, jit_numba) == ('compiled', 'numba', 'True')
    # import numba alone is about 90 MB of resident memory here; the margin leaves room for
    # allocator and library differences between machines while still failing if numba were loaded
    assert int(compiled_mb) < int(jit_mb) - 40, (compiled_mb, jit_mb)


def test_a_bad_mode_is_refused_by_a_node_entry_point_with_the_allowed_ones():
    script = Path(sys.executable).with_name('sim_node')
    result = subprocess.run([str(script)], env=_env(UH_KERNELS='fast'), capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert "UH_KERNELS='fast' is not a kernel mode: use one of numba, auto, compiled" in result.stderr
    assert 'Traceback' not in result.stderr


def test_compiled_without_a_built_module_is_an_error_and_auto_falls_back_to_numba(tmp_path):
    script = Path(sys.executable).with_name('controller_node')
    empty = tmp_path / 'none'
    result = subprocess.run([str(script)], env=_env(UH_KERNELS='compiled', UH_COMPILED_KERNELS_DIR=str(empty)),
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert 'no compiled kernels were built for these sources' in result.stderr
    assert 'python -m uh_team.compile_kernels' in result.stderr and str(empty) in result.stderr
    fallback = _python('import sys, uh_sim_node.helicopter; from uh_core import compiled_kernels as c; '
                       'print(c.kernel_form(), "numba" in sys.modules)',
                       UH_KERNELS='auto', UH_COMPILED_KERNELS_DIR=str(empty))
    assert fallback.returncode == 0, fallback.stderr
    # the node's start line says why it runs numba, and how to build the compiled kernels
    assert fallback.stdout.strip() == ('numba kernels (no compiled kernels were built for these sources: '
                                       'python -m uh_team.compile_kernels builds them) True')


def test_auto_with_a_module_built_for_other_sources_says_it_is_stale_and_how_to_rebuild(tmp_path):
    from importlib.machinery import EXTENSION_SUFFIXES
    old = tmp_path / f'uh_kernels_00000000000000000000{EXTENSION_SUFFIXES[0]}'
    old.write_bytes(b'built for an earlier version of the kernels')
    result = _python('import uh_sim_node.helicopter; from uh_core import compiled_kernels as c; print(c.kernel_form())',
                     UH_KERNELS='auto', UH_COMPILED_KERNELS_DIR=str(tmp_path))
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == (f'numba kernels (the compiled kernels {old.name} are stale (built for other '
                                     'kernel sources): python -m uh_team.compile_kernels rebuilds them)')


def test_the_numba_team_loop_refuses_a_process_that_runs_compiled_kernels(built):
    result = _python('import uh_sim_node.plant_kernels, uh_team.team_kernel', UH_KERNELS='compiled')
    assert result.returncode == 1
    assert 'ImportError: uh_team.team_kernel calls the kernels from numba code' in result.stderr
    assert 'UH_KERNELS=numba' in result.stderr


def test_the_module_name_follows_every_source_file(monkeypatch, tmp_path):
    # a module built for other sources is never loaded: its name carries a digest of them all
    sources = [tmp_path / f'{n}.py' for n in range(3)]
    for path in sources:
        path.write_text('x = 1\n')
    monkeypatch.setattr(compiled_kernels, '_source_files', lambda: sources)
    names = []
    for path in [None, *sources]:
        if path is not None:
            path.write_text(path.read_text() + '# edited\n')
        monkeypatch.setattr(compiled_kernels, '_digest_cache', [])
        names.append(compiled_kernels.library_name())
    assert len(set(names)) == 4, names
    assert all(name.startswith('uh_kernels_') for name in names)


def test_the_default_mode_is_numba_and_every_source_file_exists(monkeypatch):
    monkeypatch.delenv(compiled_kernels.MODE_VARIABLE, raising=False)
    assert compiled_kernels.mode() == 'numba'
    files = compiled_kernels._source_files()
    # gains.py lays out the gains' part of the law's parameter vector, which the kernels compile in
    assert {f.name for f in files} == {'plant_kernels.py', 'control_kernels.py', 'loop_kernels.py',
                                       'learning_kernels.py', 'isolation_kernels.py', 'impairments.py',
                                       'safety_kernels.py', 'control_layout.py', 'gains.py', 'layout.py',
                                       'compiled_kernels.py'}
    assert all(f.is_file() for f in files)
