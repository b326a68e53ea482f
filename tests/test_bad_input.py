"""Bad input where it enters a run.

Scenario and gains YAML, the command lines of run_formation and inject_fault, bags given to the
metrics reader. Each case asserts the exit status and the message
(what was wrong, where, what is allowed) and that nothing was started or written.
"""
import copy
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from uh_bringup import inject_fault, run_formation, run_outcome
from uh_report.bag_metrics import BagContentError, read_team_bag
from uh_runtime.bags.bag import BagWriter
from uh_runtime.dds.qos import qos_profile_yaml
from uh_topology.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / 'uh_topology' / 'uh_topology' / 'config'
PAPER = CONFIG / 'paper.yaml'
GAINS = CONFIG / 'paper_gains.yaml'


# -- helpers ---------------------------------------------------------------------------------------
def _run_cli(module, argv, capsys):
    """Run a CLI's main in-process; return (exit status, stderr)."""
    with pytest.raises(SystemExit) as info:
        module.main(argv)
    return info.value.code, capsys.readouterr().err


def _paper_data() -> dict:
    return yaml.safe_load(PAPER.read_text())


def _write_scenario(tmp_path, data, gains=None) -> Path:
    """Write a copy of the paper scenario (absolute gains path unless ``gains`` is a mapping to write)."""
    data = copy.deepcopy(data)
    if gains is not None:
        (tmp_path / 'gains.yaml').write_text(yaml.safe_dump(gains))
        data['gains'] = 'gains.yaml'
    elif data.get('gains') == 'paper_gains.yaml':
        data['gains'] = str(GAINS)
    path = tmp_path / 'team.yaml'
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _assert_nothing_started(out: Path):
    # rejected before the output directory is prepared: no logs, no bag, no run.json
    assert not out.exists() or not any(out.iterdir())


# -- scenario YAML through the run script ----------------------------------------------------------
def _drop_link(d):
    d['reference_links'] = []


def _orphan_follower(d):
    d['edges'] = [e for e in d['edges'] if e['uh'] != 5]


def _duplicate_id(d):
    d['uhs'][4]['id'] = 4


def _unknown_key(d):
    d['edgez'] = []


def _missing_dt(d):
    del d['dt']


def _wrong_type(d):
    d['dt'] = 'fast'


def _non_finite(d):
    d['reference']['radius'] = float('nan')


def _bad_fault(d):
    d['faults'][0]['rho'] = 1.5


SCENARIO_CASES = {
    # (mutation of the paper scenario, regex the one-line error must match)
    'unknown_key': (_unknown_key, r"team\.yaml:\d+: edgez: unknown key 'edgez'"),
    'missing_field': (_missing_dt, r"team\.yaml:(\d+:)? missing required key 'dt' \(required: name, dt, "),
    'wrong_type': (_wrong_type, r"team\.yaml:\d+: dt: expected a number \(s\), got str 'fast'"),
    'non_finite': (_non_finite, r'team\.yaml:\d+: reference\.radius: .*(NaN|nan|finite)'),
    'assumption1_leaders': (_drop_link, r'no directed path from the virtual leader \(id 0\) to leader\(s\) '
                                        r'\[1, 2, 3\]'),
    'assumption1_follower': (_orphan_follower, r'no directed path from any leader to follower\(s\) \[5\]'),
    'duplicate_id': (_duplicate_id, r'uhs\[4\]\.id: UH id 4 is already used by uhs\[3\]; ids must be unique'),
    'fault_rho': (_bad_fault, r'faults\[0\]\.rho: value 1\.5 out of range'),
}


@pytest.mark.parametrize('case', sorted(SCENARIO_CASES))
def test_bad_scenario_is_one_line_exit_2(case, tmp_path, capsys):
    mutate, message = SCENARIO_CASES[case]
    data = _paper_data()
    mutate(data)
    out = tmp_path / 'out'
    code, err = _run_cli(run_formation, ['--scenario', str(_write_scenario(tmp_path, data)), '--out', str(out)],
                         capsys)
    assert code == 2
    assert err.startswith('run_formation.sh: error: ') and err.count('\n') == 1, err
    assert __import__('re').search(message, err), err
    _assert_nothing_started(out)


def test_yaml_syntax_error_names_the_line(tmp_path, capsys):
    text = PAPER.read_text().replace('dt: 0.01 ', 'dt: [0.01 ', 1)
    path = tmp_path / 'broken.yaml'
    path.write_text(text)
    line = next(n for n, row in enumerate(text.splitlines(), 1) if row.startswith('dt: ['))
    code, err = _run_cli(run_formation, ['--scenario', str(path), '--out', str(tmp_path / 'o')], capsys)
    assert code == 2
    # the parser reports where it noticed the problem: on or shortly after the broken line
    reported = int(__import__('re').search(r'broken\.yaml:(\d+): YAML syntax error', err).group(1))
    assert line <= reported <= line + 2, err


def test_missing_scenario_file(tmp_path, capsys):
    code, err = _run_cli(run_formation, ['--scenario', str(tmp_path / 'nope.yaml'), '--out', str(tmp_path / 'o')],
                         capsys)
    assert code == 2 and 'nope.yaml' in err and 'error:' in err


GAINS_CASES = {
    'unknown_key': (lambda g: g['/**']['ros__parameters']['outer'].__setitem__('kk', 1.0),
                    r"gains\.yaml:\d+: outer: unknown key\(s\) \['kk'\]; allowed: k, r, "),
    'missing_key': (lambda g: g['/**']['ros__parameters']['outer'].pop('k'), r"missing key\(s\) \['k'\]"),
    'wrong_type': (lambda g: g['/**']['ros__parameters'].__setitem__('beta', 'two'),
                   r"beta must be a number, got 'two'"),
    'non_finite': (lambda g: g['/**']['ros__parameters']['inner'].__setitem__('k', float('inf')),
                   r'k must be finite, got inf'),
}


@pytest.mark.parametrize('case', sorted(GAINS_CASES))
def test_bad_gains_file_is_reported_before_any_node_starts(case, tmp_path, capsys):
    mutate, message = GAINS_CASES[case]
    gains = yaml.safe_load(GAINS.read_text())
    mutate(gains)
    out = tmp_path / 'out'
    code, err = _run_cli(run_formation, ['--scenario', str(_write_scenario(tmp_path, _paper_data(), gains)),
                                         '--out', str(out)], capsys)
    assert code == 2 and err.count('\n') == 1, err
    assert __import__('re').search(message, err), err
    _assert_nothing_started(out)


def test_unreadable_gains_file(tmp_path, capsys):
    data = _paper_data()
    data['gains'] = 'missing_gains.yaml'
    path = tmp_path / 'team.yaml'
    path.write_text(yaml.safe_dump(data))
    code, err = _run_cli(run_formation, ['--scenario', str(path), '--out', str(tmp_path / 'o')], capsys)
    assert code == 2
    assert "cannot read the gains file" in err and 'missing_gains.yaml' in err


# -- run_formation command line --------------------------------------------------------------------
RUN_CASES = {
    'unknown_option': (['--speed', '2'], r'unrecognized arguments: --speed 2'),
    'bad_case': (['--case', 'case3'], r"argument --case: invalid choice: 'case3'"),
    'bad_clock': (['--clock', 'fast'], r"argument --clock: invalid choice: 'fast'"),
    'not_a_number': (['--rate', 'quick'], r"argument --rate: invalid float value: 'quick'"),
    'rate_range': (['--rate', '0'], r'--rate 0\.0: allowed 0\.01 \.\. 1000'),
    'rate_nan': (['--rate', 'nan'], r'--rate nan: allowed 0\.01 \.\. 1000'),
    'duration': (['--duration', '-5'], r'--duration -5\.0: allowed > 0 \.\. 1e6 s'),
    'duration_inf': (['--duration', 'inf'], r'--duration inf: allowed > 0'),
    # one rule for durations, the scenario file's: a whole number of control periods, at least one
    'duration_steps': (['--duration', '1.234'], r'--duration 1\.234 s is not a whole number of control '
                                                r'periods dt = 0\.01 s; allowed: a multiple of dt'),
    'duration_short': (['--duration', '0.005'], r'--duration 0\.005 s is shorter than one control period'),
    'domain': (['--domain-id', '300'], r'--domain-id 300: allowed 0\.\.232'),
    'startup_timeout': (['--startup-timeout', '0'], r'--startup-timeout 0\.0: allowed > 0'),
    'stale_timeout': (['--stale-timeout', '-1'], r'--stale-timeout -1\.0: allowed > 0'),
    'loss_range': (['--hosts', 'netns', '--loss', '120'], r'--loss 120\.0: allowed 0 \.\. 100'),
    'loss_without_netns': (['--loss', '10'], r'--loss 10 needs --hosts netns'),
    'respawn_lockstep': (['--respawn'], r'--respawn needs --clock realtime'),
    'respawn_layout': (['--respawn', '--clock', 'realtime', '--processes', 'per-uh'],
                       r'--respawn needs --processes per-node'),
    'netns_single': (['--hosts', 'netns', '--processes', 'single'], r'--hosts netns cannot run --processes single'),
    'bad_hosts': (['--hosts', 'cloud'], r"argument --hosts: invalid choice: 'cloud'"),
    'workers_zero': (['--processes', 'workers', '--workers', '0'], r'--workers 0: allowed 1 or more'),
    'workers_layout': (['--workers', '2'], r'--workers needs --processes workers \(the layout is per-node\)'),
}


@pytest.mark.parametrize('case', sorted(RUN_CASES))
def test_run_formation_rejects_bad_options(case, tmp_path, capsys):
    argv, message = RUN_CASES[case]
    out = tmp_path / 'out'
    code, err = _run_cli(run_formation, [*argv, '--out', str(out)], capsys)
    assert code == 2
    assert __import__('re').search(message, err), err
    assert 'Traceback' not in err
    _assert_nothing_started(out)


def test_out_that_is_not_empty_is_refused_without_force(tmp_path, capsys):
    out = tmp_path / 'out'
    out.mkdir()
    (out / 'precious.txt').write_text('keep me')
    code, err = _run_cli(run_formation, ['--out', str(out), '--duration', '1'], capsys)
    assert code == 2
    assert f'--out {out}: exists and is not empty (use --force to replace its content)' in err
    assert (out / 'precious.txt').read_text() == 'keep me'


@pytest.mark.parametrize('where, message', [
    ('file/sub', 'cannot write there: Not a directory'),
    ('file', 'exists and is not a directory'),
    ('/sys/uh_reliability_test', 'cannot write there: '),  # sysfs: read-only even for root
])
def test_unwritable_out_is_refused(where, message, tmp_path, capsys):
    (tmp_path / 'file').write_text('')
    out = Path(where) if where.startswith('/') else tmp_path / where
    if where.startswith('/sys') and not Path('/sys').is_dir():
        pytest.skip('no /sys on this machine')
    code, err = _run_cli(run_formation, ['--out', str(out), '--duration', '1'], capsys)
    assert code == 2
    assert f'--out {out}: {message}' in err, err


def test_run_script_error_has_no_traceback(tmp_path):
    """The shell entry point: a bad scenario is one line on stderr and exit status 2."""
    bad = tmp_path / 'bad.yaml'
    bad.write_text('name: x\ndt: 0.01\n  oops: [\n')
    proc = subprocess.run([str(ROOT / 'scripts' / 'run_formation.sh'), '--scenario', str(bad), '--out',
                           str(tmp_path / 'o')], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert 'Traceback' not in proc.stderr
    assert not (tmp_path / 'run').exists()     # refused before anything was written
    assert 'bad.yaml:' in proc.stderr and 'YAML syntax error' in proc.stderr
    assert not (tmp_path / 'o').exists()


def test_node_entry_point_with_a_bad_scenario_exits_cleanly(tmp_path):
    """A node started by hand with a broken scenario says why and exits 2 (bad input); it never joins a team."""
    data = _paper_data()
    _drop_link(data)
    path = _write_scenario(tmp_path, data)
    script = Path(sys.executable).with_name('sim_node')
    proc = subprocess.run([str(script), '--ros-args', '-p', f'scenario:={path}', '-p', 'uh_id:=1'],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert 'Traceback' not in proc.stderr
    assert not (tmp_path / 'run').exists()     # refused before anything was written
    assert 'error:' in proc.stderr and 'no directed path from the virtual leader' in proc.stderr


# -- inject_fault command line ---------------------------------------------------------------------
INJECT_CASES = {
    'unknown_option': (['--uh', '1', '--channel', 'collective', '--force', '3'], r'unrecognized arguments: --force 3'),
    'missing_uh': (['--channel', 'collective'], r'the following arguments are required: --uh'),
    'unknown_channel': (['--uh', '1', '--channel', 'aileron'], r"argument --channel: invalid choice: 'aileron'"),
    'rho_above_one': (['--uh', '1', '--channel', 'collective', '--rho', '1.5'],
                      r'--rho 1\.5: allowed 0 \.\. 1 \(1 = healthy, 0 = stuck\)'),
    'rho_negative': (['--uh', '1', '--channel', 'lateral', '--rho', '-0.1'], r'--rho -0\.1: allowed 0 \.\. 1'),
    'bias_nan': (['--uh', '1', '--channel', 'collective', '--bias', 'nan'], r'--bias nan: must be a finite number'),
    'amplitude_inf': (['--uh', '1', '--channel', 'collective', '--amplitude', 'inf'],
                      r'--amplitude inf: must be a finite number'),
    'onset_negative': (['--uh', '1', '--channel', 'collective', '--onset', '-1'],
                       r'fault onset_time must be >= 0 s, got -1\.0 on channel 0'),
    'uh_zero': (['--uh', '0', '--channel', 'collective'], r'--uh 0: helicopter indices start at 1'),
    'domain': (['--uh', '1', '--channel', 'collective', '--domain-id', '999'], r'--domain-id 999: allowed 0\.\.232'),
    'timeout': (['--uh', '1', '--channel', 'collective', '--timeout', '0'], r'--timeout 0\.0: allowed > 0'),
}


@pytest.mark.parametrize('case', sorted(INJECT_CASES))
def test_inject_fault_rejects_bad_options(case, capsys):
    argv, message = INJECT_CASES[case]
    code, err = _run_cli(inject_fault, argv, capsys)
    assert code == 2
    assert __import__('re').search(message, err), err


def test_inject_fault_without_a_team_says_so(domain_id):
    """Valid values but no team in the domain: exit 1 with the reason, after --timeout."""
    proc = subprocess.run([str(ROOT / 'scripts' / 'inject_fault.sh'), '--uh', '2', '--channel', 'collective',
                           '--rho', '0.5', '--domain-id', str(domain_id), '--timeout', '1'],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1
    assert f'nobody subscribes to /uh2/fault in DDS domain {domain_id}' in proc.stderr
    # and it points to the fix: where to look for the team, and how to name its domain
    assert f'uh node list --domain-id {domain_id}' in proc.stderr and '--domain-id N' in proc.stderr
    assert 'Traceback' not in proc.stderr


# -- bags given to the metrics reader --------------------------------------------------------------
@pytest.fixture(scope='module')
def small_bag(tmp_path_factory):
    """Write a complete team bag with the project's bag writer: 40 steps of reference and states."""
    import numpy as np

    from uh_core.reference import VirtualLeaderReference
    from uh_runtime import messages as m
    from uh_runtime.dds.cdr import codec
    from uh_wire.wire import reference_to_msg, state_to_msg

    paper = load_scenario('paper')
    ref = VirtualLeaderReference(paper.reference)
    bag_dir = tmp_path_factory.mktemp('bags') / 'good'
    qos = qos_profile_yaml('reliable', 'transient_local', 'keep_last', 100)
    with BagWriter(bag_dir) as bag:
        bag.add_topic('/reference', 'uh_msgs/msg/Reference', qos)
        for i in paper.ids:
            bag.add_topic(f'/uh{i}/state', 'uh_msgs/msg/UHState', qos)
        for k in range(40):
            t = k * paper.dt
            bag.write('/reference', codec(m.Reference).serialize(reference_to_msg(k, t, ref.at(t))), int(t * 1e9))
            for i in paper.ids:
                x = np.arange(12, dtype=float) + i + k
                bag.write(f'/uh{i}/state', codec(m.UHState).serialize(state_to_msg(i, k, t, x)), int(t * 1e9))
    return bag_dir, paper


def test_good_bag_reads(small_bag):
    bag_dir, paper = small_bag
    arrays = read_team_bag(bag_dir, paper)
    assert arrays['states'].shape == (40, 5, 12)
    assert arrays['states'][7, 2, 0] == 0 + 3 + 7  # x[0] = 0 + i + k for UH 3 at step 7


def _copy_bag(src: Path, dst: Path) -> Path:
    dst.mkdir()
    for f in src.iterdir():
        (dst / f.name).write_bytes(f.read_bytes())
    return dst


def test_a_run_whose_metrics_cannot_be_computed_says_so(small_bag, tmp_path, capsys):
    """Check that metrics that cannot be computed are reported, with no metrics.json left behind.

    The run then ends with exit status 1 and ``metrics_error`` in run.json (run_formation.run).
    """
    _, paper = small_bag
    (tmp_path / 'bag').mkdir()          # a bag directory the recorder never wrote to
    problem = run_outcome.write_metrics(tmp_path, paper, 'proposed', 1.0)
    assert problem and f'[run] metrics: cannot be computed: {problem}' in capsys.readouterr().err
    assert not (tmp_path / 'metrics.json').exists()


def test_truncated_bag_says_how_to_recover(small_bag, tmp_path):
    bag_dir, paper = small_bag
    bad = _copy_bag(bag_dir, tmp_path / 'cut')
    mcap = bad / 'good_0.mcap'
    data = mcap.read_bytes()
    mcap.write_bytes(data[: len(data) // 2])
    with pytest.raises(BagContentError, match=r'cannot open bag .*cut: .*its MCAP file good_0\.mcap is cut short '
                                              r'or damaged after \d+ of \d+ bytes.*'
                                              r'python -m uh_runtime\.bags\.bag recover'):
        read_team_bag(bad, paper)


def test_not_an_mcap_file(small_bag, tmp_path):
    bag_dir, paper = small_bag
    bad = _copy_bag(bag_dir, tmp_path / 'text')
    (bad / 'good_0.mcap').write_text('this is not a bag\n')
    with pytest.raises(BagContentError, match=r'good_0\.mcap is not an MCAP file'):
        read_team_bag(bad, paper)


def test_bag_without_metadata(small_bag, tmp_path):
    bag_dir, paper = small_bag
    bad = _copy_bag(bag_dir, tmp_path / 'nometa')
    (bad / 'metadata.yaml').unlink()
    with pytest.raises(BagContentError, match=r'it has no metadata\.yaml'):
        read_team_bag(bad, paper)


def test_bag_path_that_is_a_file_or_missing(small_bag, tmp_path):
    bag_dir, paper = small_bag
    with pytest.raises(BagContentError, match=r'it is a file; give the bag directory'):
        read_team_bag(bag_dir / 'good_0.mcap', paper)
    with pytest.raises(BagContentError, match=r'no such directory'):
        read_team_bag(tmp_path / 'absent', paper)


def test_bag_without_the_team_topics(tmp_path):
    with BagWriter(tmp_path / 'empty'):
        pass
    with pytest.raises(BagContentError, match=r'has no /reference messages: not a team run'):
        read_team_bag(tmp_path / 'empty', load_scenario('paper'))


def test_invalid_messages_in_a_bag_are_left_out_and_counted(tmp_path):
    """Leave out a state with NaN or another UH's id, as the receiving nodes do.

    Such a state is what a faulty publisher puts on the wire, and the recorder faithfully keeps it;
    it is left out of the arrays like the receiving nodes leave it out.
    """
    import numpy as np

    from uh_core.reference import VirtualLeaderReference
    from uh_runtime import messages as m
    from uh_runtime.dds.cdr import codec
    from uh_wire.wire import reference_to_msg, state_to_msg

    paper = load_scenario('paper')
    ref = VirtualLeaderReference(paper.reference)
    qos = qos_profile_yaml('reliable', 'transient_local', 'keep_last', 100)
    enc = codec(m.UHState).serialize
    with BagWriter(tmp_path / 'rogue') as bag:
        bag.add_topic('/reference', 'uh_msgs/msg/Reference', qos)
        bag.add_topic('/uh2/state', 'uh_msgs/msg/UHState', qos)
        for k in range(3):
            bag.write('/reference', codec(m.Reference).serialize(reference_to_msg(k, k * 0.01, ref.at(k * 0.01))), k)
            bag.write('/uh2/state', enc(state_to_msg(2, k, k * 0.01, np.ones(12))), k)
        bag.write('/uh2/state', enc(state_to_msg(2, 1, 0.01, np.full(12, math.nan))), 5)
        bag.write('/uh2/state', enc(state_to_msg(3, 2, 0.02, np.zeros(12))), 6)
    arrays = read_team_bag(tmp_path / 'rogue', paper)
    assert np.array_equal(arrays['states'][:, 1], np.ones((3, 12)))
    assert arrays['rejected'] == {'/uh2/state': 2}


@pytest.mark.parametrize('command', [['scripts/inject_fault.sh', '--uh', '1', '--channel', 'collective', '--rho', '0.5',
                                      '--onset', '1'],
                                     ['scripts/run_formation.sh', '--duration', '1'],
                                     ['.venv/bin/uh', 'topic', 'list']])
def test_a_bad_discovery_range_is_named_with_what_is_allowed(command, tmp_path):
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LAN')
    env.pop('CYCLONEDDS_URI', None)
    if command[0] == 'scripts/run_formation.sh':
        command = command + ['--out', str(tmp_path / 'run')]
    proc = subprocess.run([str(ROOT / command[0]), *command[1:]], env=env, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode in (1, 2), proc
    assert "ROS_AUTOMATIC_DISCOVERY_RANGE='LAN'; allowed: LOCALHOST, SUBNET, OFF, SYSTEM_DEFAULT" in proc.stderr
    assert 'Traceback' not in proc.stderr
    assert not (tmp_path / 'run').exists()     # refused before anything was written
    assert not (tmp_path / 'run').exists()     # refused before anything was written


# -- every command: one line, exit 2, nothing started ----------------------------------------------
def _status(main, argv, capsys):
    """Run a command's main in-process; return (exit status, stderr) whether it returns or exits."""
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    return code, capsys.readouterr().err


def _one_line(err: str) -> bool:
    return err.count('\n') == 1 and 'Traceback' not in err


def _gains_scenario(tmp_path, edit) -> Path:
    """Write the paper scenario naming a copy of its gains file changed by ``edit`` (text -> text)."""
    (tmp_path / 'gains.yaml').write_text(edit(GAINS.read_text()))
    data = _paper_data()
    data['gains'] = 'gains.yaml'
    path = tmp_path / 'team.yaml'
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _nan_beta(text):
    return text.replace('    beta: 2.0 ', '    beta: .nan ', 1)


def _repeated_beta(text):
    return text.replace('    beta: 2.0 ', '    beta: 2.0\n    beta: 3.0 ', 1)


def _line_of(text: str, start: str, nth: int = 1) -> int:
    """1-based line of the ``nth`` line of ``text`` starting with ``start``."""
    return [n for n, row in enumerate(text.splitlines(), 1) if row.startswith(start)][nth - 1]


@pytest.mark.parametrize('edit, message', [
    # the gains file and the line of the entry ({n}: computed from the edited file), not the scenario's name
    (_nan_beta, r'gains\.yaml:{beta}: beta must be finite, got nan'),
    (_repeated_beta, r"gains\.yaml:{beta2}: key 'beta' repeated \(first at line {beta}\)"),
    (lambda t: t.replace('      kappa: 20.0 ', '      kappx: 20.0 ', 1),
     r"gains\.yaml:{kappx}: outer: unknown key\(s\) \['kappx'\]"),
])
@pytest.mark.parametrize('command', ['uh-simulate', 'run_formation', 'compare'])
def test_a_bad_gains_file_is_named_with_its_line_by_every_command(command, edit, message, tmp_path, capsys):
    from uh_bringup import compare
    from uh_team import simulate_cli
    main = {'uh-simulate': simulate_cli.main, 'run_formation': run_formation.main, 'compare': compare.main}[command]
    scenario = _gains_scenario(tmp_path, edit)
    text = (tmp_path / 'gains.yaml').read_text()
    message = message.format(beta=_line_of(text, '    beta:'), beta2=_line_of(text, '    beta:', 2) if
                             text.count('    beta:') > 1 else 0, kappx=_line_of(text, '      kappx:') if
                             'kappx' in text else 0)
    out = tmp_path / 'out'
    code, err = _status(main, ['--scenario', str(scenario), '--out', str(out)], capsys)
    assert code == 2 and _one_line(err), err
    assert __import__('re').search(message, err), err
    assert 'Error:' not in err      # no exception class name in front of the message
    assert not out.exists()


SIMULATE_CASES = {
    # (arguments besides --out, regex of the one-line message); every one refused before the simulation
    'unwritable_out': (['--out', '{tmp}/file/sub'], r"--out '.*file/sub': cannot write there \(Not a directory\)"),
    'out_is_a_file': (['--out', '{tmp}/file'], r"--out '.*file' exists and is not a directory"),
    'empty_out': (['--out', ''], r"argument --out: '': give a directory"),
    'scenario_is_a_directory': (['--scenario', '{tmp}'], r"scenario '.*' is a directory; give a YAML file"),
    'empty_scenario': (['--scenario', ''], r"scenario '': give a path to a YAML file or a bundled name"),
    'duration_steps': (['--duration', '1.234'], r'--duration 1\.234 s is not a whole number of control periods'),
    'duration_nan': (['--duration', 'nan'], r'--duration must be a finite number of seconds > 0, got nan'),
    'unknown_case': (['--case', 'case3'], r"argument --case: invalid choice: 'case3'"),
    'unknown_option': (['--speed', '2'], r'unrecognized arguments: --speed 2; see uh-simulate --help'),
}


@pytest.mark.parametrize('case', sorted(SIMULATE_CASES))
def test_uh_simulate_rejects_bad_input_before_running(case, tmp_path, capsys):
    from uh_team import simulate_cli
    argv, message = SIMULATE_CASES[case]
    (tmp_path / 'file').write_text('')
    argv = [a.replace('{tmp}', str(tmp_path)) for a in argv]
    if '--out' not in argv:
        argv += ['--out', str(tmp_path / 'out')]
    code, err = _status(simulate_cli.main, argv, capsys)
    assert code == 2 and _one_line(err), err
    assert __import__('re').search(message, err), err
    assert not (tmp_path / 'out').exists() and not list(tmp_path.glob('**/metrics.json'))


def test_uh_simulate_defaults_to_the_paper_scenario():
    from uh_team import simulate_cli
    assert simulate_cli.build_parser().parse_args(['--out', 'x']).scenario == 'paper'


@pytest.mark.parametrize('argv, message', [
    (['campaign_paper_faults', '--out', '{tmp}/file/sub', '--runs', '1'],
     r"--out '.*file/sub': cannot write there \(Not a directory\); choose a directory you can write to"),
    (['campaign_paper_faults', '--out', ''], r"argument --out: '': give a directory"),
    (['', '--out', '{tmp}/out'], r"SPEC '': give a campaign spec YAML file or a bundled name"),
    (['{tmp}', '--out', '{tmp}/out'], r"campaign spec '.*' is a directory"),
])
def test_uh_campaign_rejects_bad_input_in_one_line(argv, message, tmp_path, capsys):
    from uh_campaign import cli
    (tmp_path / 'file').write_text('')
    code, err = _status(cli.main, [a.replace('{tmp}', str(tmp_path)) for a in argv], capsys)
    assert code == 2 and _one_line(err), err
    assert __import__('re').search(message, err), err
    assert not (tmp_path / 'out').exists() and not (tmp_path / 'file').is_dir()


@pytest.fixture(scope='module')
def simulated_run(tmp_path_factory):
    """Run uh-simulate for 1 s of the paper scenario, for the report's cases."""
    from uh_team import simulate_cli
    out = tmp_path_factory.mktemp('sim') / 'run'
    assert simulate_cli.main(['--duration', '1', '--out', str(out)]) == 0
    return out


def test_uh_report_names_a_broken_scenario_file_not_a_missing_one(simulated_run, tmp_path, capsys):
    from uh_report import report
    broken = tmp_path / 'broken.yaml'
    broken.write_text('name: x\ndt: 0.01\n  oops: [\n')
    code, err = _status(report.main, [str(simulated_run), '--scenario', str(broken), '--out', str(tmp_path / 'r')],
                        capsys)
    assert code == 2 and 'broken.yaml:3: YAML syntax error' in err, err
    assert not (tmp_path / 'r').exists()


@pytest.mark.parametrize('argv, message', [
    (['{run}', '--out', '{tmp}/file'], r'--out .*file: exists and is not a directory'),
    (['{run}', '--out', ''], r"argument --out: '': give a directory"),
    ([''], r"RUN_DIR '': give a run directory"),
])
def test_uh_report_rejects_bad_input(argv, message, simulated_run, tmp_path, capsys):
    from uh_report import report
    (tmp_path / 'file').write_text('keep')
    argv = [a.replace('{run}', str(simulated_run)).replace('{tmp}', str(tmp_path)) for a in argv]
    code, err = _status(report.main, argv, capsys)
    assert code == 2 and __import__('re').search(message, err), err
    assert 'Traceback' not in err and (tmp_path / 'file').read_text() == 'keep'


COMPARE_CASES = {
    'unwritable_out': (['--out', '{tmp}/file/sub'], r'--out .*file/sub: cannot write there: Not a directory'),
    'out_is_a_file': (['--out', '{tmp}/file'], r'--out .*file: exists and is not a directory'),
    'out_not_empty': (['--out', '{tmp}/full'], r'--out .*full: exists and is not empty; choose a new or empty'),
    'missing_value': (['--out'], r'argument --out: expected one argument; see compare.sh --help'),
    'duration': (['--duration', '-1'], r'--duration -1 s is shorter than one control period'),
    'duration_steps': (['--duration', '0.1234'], r'--duration 0\.1234 s is not a whole number of control periods'),
    'scenario': (['--scenario', 'nope.yaml'], r"no scenario file 'nope\.yaml'"),
    'unknown_option': (['--bogus'], r'unrecognized arguments: --bogus; see compare.sh --help'),
}


@pytest.mark.parametrize('case', sorted(COMPARE_CASES))
def test_compare_checks_everything_before_the_first_run(case, tmp_path, capsys):
    from uh_bringup import compare
    argv, message = COMPARE_CASES[case]
    (tmp_path / 'file').write_text('')
    (tmp_path / 'full').mkdir()
    (tmp_path / 'full' / 'precious.txt').write_text('keep me')
    argv = [a.replace('{tmp}', str(tmp_path)) for a in argv]
    if '--out' not in argv:
        argv += ['--out', str(tmp_path / 'out')]
    code, err = _status(compare.main, ['--simulate', *argv], capsys)
    assert code == 2 and _one_line(err), err
    assert __import__('re').search(message, err), err
    assert not (tmp_path / 'out').exists() and (tmp_path / 'full' / 'precious.txt').read_text() == 'keep me'


def test_compare_script_with_an_unwritable_out_is_one_line(tmp_path):
    """The shell entry point: before, a raw mkdir error and exit 1."""
    (tmp_path / 'file').write_text('')
    proc = subprocess.run([str(ROOT / 'scripts' / 'compare.sh'), '--simulate', '--out', str(tmp_path / 'file' / 'x')],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and _one_line(proc.stderr), proc.stderr
    assert proc.stderr.startswith('compare.sh: error: --out ')


@pytest.mark.parametrize('argv, message', [
    (['--out', '{tmp}/file/x.json'], r'--out .*file/x\.json: .*file is a file, not a directory'),
    (['--out', '{tmp}'], r'--out .*: is a directory; give the results file'),
    (['--keep', '{tmp}/file'], r'--keep .*file: exists and is not a directory'),
    (['--sections', 'bogus'], r"argument --sections: invalid choice: 'bogus'"),
])
def test_bench_checks_its_paths_before_any_benchmark(argv, message, tmp_path):
    (tmp_path / 'file').write_text('')
    argv = [a.replace('{tmp}', str(tmp_path)) for a in argv]
    if '--out' not in argv:
        argv += ['--out', str(tmp_path / 'results.json')]
    proc = subprocess.run([str(ROOT / 'scripts' / 'bench.sh'), '--quick', '--sections', 'components', *argv],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and _one_line(proc.stderr), proc.stderr
    assert __import__('re').search(message, proc.stderr), proc.stderr
    assert not (tmp_path / 'results.json').exists()


def test_bench_resolves_a_relative_out_against_where_it_was_started(tmp_path):
    (tmp_path / 'here').mkdir()
    proc = subprocess.run([str(ROOT / 'scripts' / 'bench.sh'), '--out', 'here'], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120)
    # 'here' is the caller's directory tmp_path/here, not a path under the repository
    assert proc.returncode == 2 and '--out here: is a directory' in proc.stderr, proc.stderr
    assert not (ROOT / 'here').exists()


@pytest.mark.parametrize('argv, message', [
    (['node', 'list', '--spin-time', 'nan'], r"argument --spin-time: 'nan': allowed a finite number of seconds > 0"),
    (['topic', 'echo', '/uh1/state', '--timeout', '-1'], r"argument --timeout: '-1': allowed a finite number"),
    (['topic', 'hz', '/uh1/state', '--window', '0'], r"argument --window/-w: '0': allowed an integer >= 1"),
    (['topic', 'echo', 'bad name', '--timeout', '1'], r"invalid topic name '/bad name'"),
    (['topic', 'info', '1bad'], r"invalid topic name '/1bad'"),
    (['param', 'get', 'bad node', 'x', '--spin-time', '1'], r"node '/bad node': invalid node name 'bad node'"),
    (['node', 'list', '--domain-id', '-1'], r'--domain-id -1 is outside 0\.\.232'),
    (['bogus'], r"invalid choice: 'bogus'.*; see uh --help"),
])
def test_uh_cli_rejects_bad_input_with_exit_2(argv, message, domain_id, capsys):
    from uh_runtime.cli import uh as cli
    code, err = _status(cli.main, argv, capsys)
    assert code == 2 and _one_line(err), err
    assert __import__('re').search(message, err), err


def test_usage_errors_are_one_line_naming_the_help(tmp_path, capsys):
    # argparse printed the whole usage first: 13 lines for run_formation.sh
    code, err = _run_cli(run_formation, ['--domain-id', 'abc', '--out', str(tmp_path / 'o')], capsys)
    assert code == 2 and _one_line(err), err
    assert err == ("run_formation.sh: error: argument --domain-id: invalid int value: 'abc'; "
                   'see run_formation.sh --help\n')


@pytest.mark.parametrize('params, message', [
    (['output:={tmp}/file/bag'], "parameter 'output': cannot create bag in"),
    (['output:={tmp}/full'], "parameter 'output': bag directory .*full exists and is not empty"),
    (['output:='], "parameter 'output' is empty: give the bag directory to create"),
    (['output:={tmp}/bag', "topics:=['bad name']"], "parameter 'topics': invalid topic name 'bad name'"),
])
def test_recorder_with_a_bad_parameter_exits_2_in_one_line(params, message, tmp_path, domain_id):
    (tmp_path / 'file').write_text('')
    (tmp_path / 'full').mkdir()
    (tmp_path / 'full' / 'precious.txt').write_text('keep me')
    args = [a for p in params for a in ('-p', p.replace('{tmp}', str(tmp_path)))]
    proc = subprocess.run([str(Path(sys.executable).with_name('recorder_node')), '--ros-args', *args],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and _one_line(proc.stderr), proc.stderr
    assert __import__('re').search(message, proc.stderr), proc.stderr
    assert not (tmp_path / 'bag').exists() and (tmp_path / 'full' / 'precious.txt').read_text() == 'keep me'


def test_inject_fault_decides_quickly_that_no_team_is_there(domain_id):
    """Without --timeout, an empty domain is reported after the 2 s discovery window, not after 10 s."""
    import time
    start = time.monotonic()
    proc = subprocess.run([str(ROOT / 'scripts' / 'inject_fault.sh'), '--uh', '2', '--channel', 'collective',
                           '--domain-id', str(domain_id)], capture_output=True, text=True, timeout=60)
    elapsed = time.monotonic() - start
    assert proc.returncode == 1 and _one_line(proc.stderr), proc.stderr
    assert f'no node at all was discovered there within {inject_fault.NO_TEAM_S:g} s' in proc.stderr
    # the window plus the start of a Python process: under 1 s on an idle machine; 8 s leaves room
    # for a loaded one and is still below the 10 s wait (DEFAULT_TIMEOUT_S) that applied before
    assert elapsed < 8.0, elapsed
