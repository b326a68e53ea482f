"""Bad input of a secure run and a secure injection: one line, exit status 2, nothing started (no DDS needed).

``run_formation.sh --secure`` checks its options, the layout, the domain, the backend and a given keystore
(``uh-security check``: a keystore of this scenario and safety setting, identities signed by its CA and
valid now) before its output directory is touched, so every case here leaves ``--out`` unmade.
"""
import shutil
from importlib import metadata

import pytest

from uh_bringup import inject_fault, run_formation
from uh_security import cli


@pytest.fixture(scope='module')
def paper_keys(tmp_path_factory):
    """Make a keystore of the paper scenario (safety filter on, its default)."""
    path = tmp_path_factory.mktemp('keys') / 'paper'
    assert cli.main(['create', '--scenario', 'paper', '--keystore', str(path)]) == 0
    return path


def _refused(capsys, tmp_path, *argv) -> str:
    out = tmp_path / 'out'
    with pytest.raises(SystemExit) as exc:
        run_formation.main(['--out', str(out), '--no-metrics', *argv])
    err = capsys.readouterr().err
    assert exc.value.code == 2, err
    lines = [line for line in err.splitlines() if line.startswith('run_formation.sh: error:')]
    assert len(lines) == 1 and 'Traceback' not in err, err
    assert not out.exists(), 'the run prepared its output before refusing'
    return lines[0]


@pytest.mark.parametrize('argv, message', [
    (['--secure', '--processes', 'single'], r'--processes single: .*one process per node'),
    (['--secure', '--processes', 'per-uh'], r'--processes per-uh'),
    (['--secure', '--processes', 'workers'], r'--processes workers'),
    (['--secure', '--domain-id', '231'], r'domain 231: allowed 0\.\.230'),
    (['--keystore', 'somewhere'], r'--keystore somewhere needs --secure'),
    (['--secure', '--hosts', 'netns'], r'--hosts netns: not built'),
])
def test_a_secure_run_refuses_bad_options(argv, message, tmp_path, capsys):
    assert __import__('re').search(message, _refused(capsys, tmp_path, *argv))


def test_a_secure_run_refuses_the_rclpy_backend(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv('UH_ROS_WHEELS', '1')
    assert 'UH_ROS_WHEELS=1' in _refused(capsys, tmp_path, '--secure')


def test_a_secure_run_refuses_a_directory_that_is_not_a_keystore(tmp_path, capsys):
    folder = tmp_path / 'notes'
    folder.mkdir()
    (folder / 'todo.txt').write_text('not a keystore\n')
    assert 'exists and is not a keystore' in _refused(capsys, tmp_path, '--secure', '--keystore', str(folder))


@pytest.mark.parametrize('argv, message', [
    (['--safety', 'off'], 'is the keystore of scenario paper (safety filter on), not of scenario paper (safety '
                          'filter off)'),
    (['--scenario', 'crowd'], 'not of scenario crowd'),
])
def test_a_secure_run_refuses_a_keystore_of_another_scenario_or_safety_setting(argv, message, paper_keys, tmp_path,
                                                                              capsys):
    assert message in _refused(capsys, tmp_path, '--secure', '--keystore', str(paper_keys), *argv)


def test_a_secure_run_refuses_a_foreign_certificate(paper_keys, tmp_path, capsys):
    """UH1's controller identity replaced by that of another keystore (another CA)."""
    forged = tmp_path / 'forged'
    shutil.copytree(paper_keys, forged, symlinks=True)
    other = tmp_path / 'other'
    assert cli.main(['create', '--scenario', 'paper', '--keystore', str(other)]) == 0
    for name in ('cert.pem', 'key.pem'):
        shutil.copy(other / 'enclaves' / 'uh1' / 'controller' / name, forged / 'enclaves' / 'uh1' / 'controller' / name)
    assert 'certificate of /uh1/controller is not signed by the keystore' in _refused(
        capsys, tmp_path, '--secure', '--keystore', str(forged))


@pytest.mark.skipif(metadata.version('cyclonedds').startswith('0.10.'), reason='this Python has the secure binding')
def test_a_secure_run_needs_the_binding_with_security(paper_keys, tmp_path, capsys):
    """The main virtualenv's Cyclone DDS 11.0.1 has no security plugins: the run says to use the script."""
    assert 'run scripts/run_formation.sh --secure' in _refused(capsys, tmp_path, '--secure', '--keystore',
                                                               str(paper_keys))


@pytest.mark.parametrize('argv, message', [
    (['--secure', '--keystore', '/nonexistent'], 'no operator identity'),
    (['--keystore', '/nonexistent'], '--keystore /nonexistent needs --secure'),
    (['--secure', '--domain-id', '231', '--keystore', 'KEYS'], 'domain 231: allowed 0..230'),
])
def test_a_secure_injection_refuses_bad_input(argv, message, paper_keys, capsys, monkeypatch):
    monkeypatch.delenv('ROS_SECURITY_KEYSTORE', raising=False)
    argv = [str(paper_keys) if a == 'KEYS' else a for a in argv]
    with pytest.raises(SystemExit) as exc:
        inject_fault.main(['--uh', '1', '--channel', 'collective', '--rho', '0.7', *argv])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and message in err and len(err.strip().splitlines()) == 1, err

