"""The keys of a scenario, declared once (uh_topology.scenario_keys), and the one reader of configuration text.

The declaration is what the scenario loader, the campaign spec and docs/scenario.md's key tables
follow: a key added there reaches all three. A configuration file that is not UTF-8 text is refused
in one line, as any bad input is (tests/test_bad_input.py).
"""
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from scenario_texts import paper_yaml

from uh_bringup import run_formation
from uh_campaign import cli as campaign_cli
from uh_campaign.spec import parse_spec
from uh_team import simulate_cli
from uh_topology import errors as E
from uh_topology import scenario_keys
from uh_topology.scenario import COMPENSATIONS, DEFAULT_COMPENSATION, DEFAULT_SETTLE_TIME, load_scenario, parse_scenario
from uh_topology.scenario_keys import IMPAIRMENT_KEYS, SCENARIO_KEYS, ScenarioKey, key_named, markdown_table
from uh_topology.schema import read_text_file

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / 'uh_topology' / 'uh_topology' / 'config'
DOC = ROOT / 'docs' / 'scenario.md'
#: docs/scenario.md's headings above the tables of the registry, and how each table is written.
DOC_TABLES = {'## Top-level keys': ('SCENARIO_KEYS', True), '### `impairments`': ('IMPAIRMENT_KEYS', False),
              '### `safety`': ('SAFETY_KEYS', False), '### `events`': ('EVENT_KEYS', False),
              '### `resilience`': ('RESILIENCE_KEYS', False)}


def _doc_table(heading: str) -> str:
    """Return the first table after ``heading`` in docs/scenario.md, its lines as written."""
    lines = DOC.read_text().splitlines()
    start = next(n for n, line in enumerate(lines) if line.startswith('|') and n > lines.index(heading))
    end = next((n for n in range(start, len(lines)) if not lines[n].startswith('|')), len(lines))
    return '\n'.join(lines[start:end]) + '\n'


def _generated(heading: str) -> str:
    table, required_column = DOC_TABLES[heading]
    return markdown_table(getattr(scenario_keys, table), required_column=required_column)


def _campaign(impairments: str) -> str:
    return f'name: c\nscenario: paper\nruns: 1\nduration: 1.0\nimpairments: {impairments}\n'


# -- the docs' tables are the registry's --------------------------------------------------------------
@pytest.mark.parametrize('heading', sorted(DOC_TABLES))
def test_the_docs_key_tables_are_those_of_the_registry(heading):
    assert _doc_table(heading) == _generated(heading), \
        f'docs/scenario.md, table under {heading!r}: write it as uh_topology.scenario_keys.markdown_table gives it'


def test_the_documented_default_of_delay_compensation_is_the_codes():
    row = next(line for line in _doc_table('### `impairments`').splitlines() if line.startswith('| `delay_comp'))
    assert row.split('|')[2].strip() == f'`{DEFAULT_COMPENSATION}`' == '`predict`'
    assert COMPENSATIONS == ('none', 'predict', 'reference_motion')


# -- the loader and the campaign spec read it ---------------------------------------------------------
def test_absent_keys_take_the_declared_defaults():
    data = yaml.safe_load(paper_yaml())
    for name in ('description', 'substeps', 'settle_time', 'model_mismatch', 'helicopter'):
        data.pop(name, None)
    data['impairments'] = {'loss': 0.1}
    bare = parse_scenario(yaml.safe_dump(data), source='bare')
    assert (bare.description, bare.substeps, bare.settle_time, bare.model_mismatch, bare.helicopter) == tuple(
        key_named(SCENARIO_KEYS, name).default
        for name in ('description', 'substeps', 'settle_time', 'model_mismatch', 'helicopter'))
    imp = bare.impairments
    assert imp.seed == key_named(IMPAIRMENT_KEYS, 'seed').default
    assert imp.compensation == key_named(IMPAIRMENT_KEYS, 'delay_compensation').default
    assert set(imp.delays.values()) == {key_named(IMPAIRMENT_KEYS, 'delay_steps').default}
    assert DEFAULT_SETTLE_TIME == key_named(SCENARIO_KEYS, 'settle_time').default


def test_the_loader_allows_and_requires_the_declared_top_level_keys():
    with pytest.raises(E.UnknownKeyError) as info:
        parse_scenario(paper_yaml('edgez: []'), source='team.yaml')
    assert info.value.message.endswith('allowed keys here: ' + ', '.join(
        [k.name for k in SCENARIO_KEYS if k.required] + [k.name for k in SCENARIO_KEYS if not k.required]))
    with pytest.raises(E.MissingFieldError, match=r'required: ' + ', '.join(
            k.name for k in SCENARIO_KEYS if k.required) + r'\)'):
        parse_scenario(paper_yaml().replace('\ndt: ', '\n# dt: ', 1), source='team.yaml')


SCALAR_IMPAIRMENTS = [key for key in IMPAIRMENT_KEYS if key.kind is not None]


@pytest.mark.parametrize('key', SCALAR_IMPAIRMENTS, ids=lambda key: key.name)
def test_every_scalar_impairment_key_is_checked_as_declared(key):
    if key.choices:
        bad, allowed = 'no_such_choice', 'allowed: ' + ', '.join(key.choices)
    elif key.hi is not None:
        bad, allowed = key.hi, f'allowed: [{key.lo}, {key.hi})'
    else:
        bad, allowed = key.lo - 1, f'allowed: >= {key.lo}'
    with pytest.raises(E.InvalidValueError) as info:
        parse_scenario(paper_yaml(f'impairments: {{{key.name}: {bad}}}'), source='team.yaml')
    assert info.value.path == f'impairments.{key.name}' and info.value.message.endswith(allowed)


def test_the_campaign_spec_allows_the_declared_impairment_keys_and_draws_the_seed():
    with pytest.raises(E.UnknownKeyError) as info:
        parse_spec(_campaign('{lag: 3}'), source='c.yaml', base_dir=CONFIG)
    given = [k.name for k in IMPAIRMENT_KEYS if not k.drawn_by_campaign]
    drawn = [k.name for k in IMPAIRMENT_KEYS if k.drawn_by_campaign]
    assert drawn == ['seed'] and info.value.message.endswith('allowed keys here: ' + ', '.join(given + drawn))
    with pytest.raises(E.InvalidValueError, match='the impairments seed is drawn for every draw'):
        parse_spec(_campaign('{seed: 3}'), source='c.yaml', base_dir=CONFIG)


# -- one edit of the registry reaches the loader, the campaign spec and the docs -----------------------
DUMMY = ScenarioKey('dummy_steps', 'integer >= 0: a key only this test declares', default=0, unit='control steps',
                    kind='integer', lo=0, what='a whole number of steps >= 0', null_is_default=True, per_link=True)


def test_a_key_added_to_the_registry_reaches_the_loader_the_campaign_spec_and_the_docs(monkeypatch):
    impaired = paper_yaml('impairments: {dummy_steps: 2, loss: 0.1, links: [{uh: 4, hears: 1, dummy_steps: 3}]}')
    with pytest.raises(E.UnknownKeyError):
        parse_scenario(impaired, source='team.yaml')
    with pytest.raises(E.UnknownKeyError):
        parse_spec(_campaign('{dummy_steps: 2}'), source='c.yaml', base_dir=CONFIG)
    docs_before = _generated('### `impairments`')

    monkeypatch.setattr(scenario_keys, 'IMPAIRMENT_KEYS', IMPAIRMENT_KEYS + (DUMMY,))   # the one edit

    assert parse_scenario(impaired, source='team.yaml').impairments.losses[(4, 1)] == 0.1
    with pytest.raises(E.InvalidValueError, match=r'impairments\.dummy_steps: value -1 out of range; allowed: >= 0'):
        parse_scenario(paper_yaml('impairments: {dummy_steps: -1}'), source='team.yaml')
    with pytest.raises(E.WrongTypeError, match=r'links\[0\]\.dummy_steps: expected a whole number of steps'):
        parse_scenario(paper_yaml('impairments: {links: [{uh: 4, hears: 1, dummy_steps: 0.5}]}'), source='team.yaml')
    with pytest.raises(E.UnknownKeyError, match=r'allowed keys here: uh, hears, .*, loss, dummy_steps$'):
        parse_scenario(paper_yaml('impairments: {links: [{uh: 4, hears: 1, lag: 1}]}'), source='team.yaml')

    spec = parse_spec(_campaign('{dummy_steps: 2}'), source='c.yaml', base_dir=CONFIG)
    assert spec.impairments == {'dummy_steps': 2}
    with pytest.raises(E.InvalidValueError) as info:
        parse_spec(_campaign('{dummy_steps: -3}'), source='c.yaml', base_dir=CONFIG)
    assert info.value.path == 'impairments.dummy_steps' and info.value.line == 5

    docs_after = _generated('### `impairments`')
    assert docs_after == docs_before + '| `dummy_steps` | 0 | control steps | integer >= 0: a key only this test ' \
                                       'declares |\n'
    assert _doc_table('### `impairments`') != docs_after     # the docs test now asks for the row


def test_a_key_the_reader_does_not_know_how_to_read_is_refused_at_once():
    with pytest.raises(ValueError, match="kind 'list'"):
        ScenarioKey('x', 'y', kind='list')


# -- a file that is not UTF-8 text ----------------------------------------------------------------------
BAD_BYTE = b'# caf\x80 au lait\n'


def _not_utf8(path: Path, text: str) -> tuple:
    """Write ``text`` with a line holding byte 0x80 after it; return (path, offset of the byte, its line)."""
    data = text.encode() + BAD_BYTE
    path.write_bytes(data)
    offset = data.index(b'\x80')
    return path, offset, data[:offset].count(b'\n') + 1


def test_the_schema_reader_names_the_file_the_byte_its_offset_and_line(tmp_path):
    path, offset, line = _not_utf8(tmp_path / 'team.yaml', paper_yaml())
    with pytest.raises(E.ScenarioSyntaxError) as info:
        read_text_file(path)
    assert str(info.value) == (f'{path}:{line}: not UTF-8 text: byte 0x80 at offset {offset}; '
                               'allowed: a YAML text file in UTF-8')
    with pytest.raises(E.ScenarioSyntaxError, match=f'team.yaml:{line}: not UTF-8 text: byte 0x80'):
        load_scenario(path)


def test_the_schema_reader_reads_line_ends_as_text_mode_does(tmp_path):
    path = tmp_path / 'crlf.yaml'
    path.write_bytes(paper_yaml().replace('\n', '\r\n').encode() + b'# caf\xc3\xa9\r# end\r\n')
    assert read_text_file(path) == path.read_text(encoding='utf-8')
    assert load_scenario(path).num_steps == parse_scenario(paper_yaml()).num_steps


@pytest.mark.parametrize('command', ['uh-simulate', 'run_formation'])
def test_a_scenario_that_is_not_utf8_is_one_line_exit_2(command, tmp_path, capsys):
    path, offset, line = _not_utf8(tmp_path / 'team.yaml', paper_yaml())
    main = {'uh-simulate': simulate_cli.main, 'run_formation': run_formation.main}[command]
    out = tmp_path / 'out'
    try:
        code = main(['--scenario', str(path), '--out', str(out)])
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and err.count('\n') == 1 and 'Traceback' not in err, err
    assert f'team.yaml:{line}: not UTF-8 text: byte 0x80 at offset {offset}; allowed: ' in err, err
    assert 'Error:' not in err and not out.exists()


def test_a_gains_file_that_is_not_utf8_is_one_line_exit_2(tmp_path, capsys):
    _not_utf8(tmp_path / 'gains.yaml', (CONFIG / 'paper_gains.yaml').read_text())
    scenario = tmp_path / 'team.yaml'
    scenario.write_text(paper_yaml().replace(f'gains: {CONFIG / "paper_gains.yaml"}', 'gains: gains.yaml'))
    code = simulate_cli.main(['--scenario', str(scenario), '--out', str(tmp_path / 'out')])
    err = capsys.readouterr().err
    assert code == 2 and err.count('\n') == 1 and 'Traceback' not in err, err
    assert re.search(r'gains\.yaml:\d+: not UTF-8 text: byte 0x80 at offset \d+', err), err


def test_a_campaign_spec_that_is_not_utf8_is_one_line_exit_2(tmp_path, capsys):
    path, offset, line = _not_utf8(tmp_path / 'spec.yaml', 'name: c\nscenario: paper\nruns: 1\n')
    try:
        code = campaign_cli.main([str(path), '--out', str(tmp_path / 'out')])
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and err.count('\n') == 1 and 'Traceback' not in err, err
    assert f'spec.yaml:{line}: not UTF-8 text: byte 0x80 at offset {offset}' in err, err
    assert not (tmp_path / 'out').exists()


@pytest.mark.parametrize('command', ['uh-simulate', 'run_formation.sh'])
def test_the_commands_refuse_a_scenario_that_is_not_utf8_without_a_traceback(command, tmp_path):
    path, offset, _ = _not_utf8(tmp_path / 'team.yaml', paper_yaml())
    argv = ([str(Path(sys.executable).with_name('uh-simulate'))] if command == 'uh-simulate'
            else [str(ROOT / 'scripts' / 'run_formation.sh')])
    proc = subprocess.run([*argv, '--scenario', str(path), '--out', str(tmp_path / 'out')], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert 'Traceback' not in proc.stderr, proc.stderr
    # the error is the last line (the script's set-up may report itself before, as in tests/test_bad_input.py)
    assert f'{path}:' in proc.stderr.splitlines()[-1] and \
        f'not UTF-8 text: byte 0x80 at offset {offset}' in proc.stderr.splitlines()[-1], proc.stderr
    assert command != 'uh-simulate' or proc.stderr.count('\n') == 1, proc.stderr
    assert not (tmp_path / 'out').exists()
