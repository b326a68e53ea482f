"""The controller gains are declared once (``GAINS`` of uh_controller_node/gains.py); every use follows.

The records, the reader of the gains file (its errors with file and line), the slots of the law's
parameter vector and their ``L_*``/``CP_*`` constants, the gains as ROS parameters and the tables of
docs/scenario.md#gains-file come from the one table; a gain declared in a copy of the package
reaches all of them.
"""
import ast
import dataclasses
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from uh_controller_node import control_kernels as ck
from uh_controller_node import gains as G
from uh_topology.schema import parse_yaml

ROOT = Path(__file__).resolve().parents[1]
GAINS_FILE = ROOT / 'uh_topology' / 'uh_topology' / 'config' / 'paper_gains.yaml'


def _docs_gains_tables() -> str:
    """Give the table lines of the "Gains file" section of docs/scenario.md (tables separated by a blank line)."""
    text = (ROOT / 'docs' / 'scenario.md').read_text()
    section = text.split('\n## Gains file\n', 1)[1].split('\n## ', 1)[0]
    blocks, current = [], []
    for line in section.splitlines():
        if line.startswith('|'):
            current.append(line)
        elif current:
            blocks.append('\n'.join(current))
            current = []
    return '\n\n'.join(blocks + (['\n'.join(current)] if current else [])) + '\n'


def test_the_docs_gains_tables_are_the_registry():
    assert _docs_gains_tables() == G.gains_markdown_table(), (
        'docs/scenario.md#gains-file differs from GAINS: paste uh_controller_node.gains.gains_markdown_table()')


def test_the_records_hold_every_declared_gain():
    loop_fields = [f.name for f in dataclasses.fields(G.LoopGains)]
    assert loop_fields == list(dict.fromkeys(g.attr.partition('.')[0] for g in G.LOOP_GAINS))
    top = [f.name for f in dataclasses.fields(G.ControllerGains)]
    assert top[0] == 'case' and set(top[1:]) == {g.attr for g in G.TOP_GAINS} | set(G.LOOPS)
    assert {g.attr.partition('.')[2] for g in G.LOOP_GAINS if g.attr.startswith('rbf.')} == \
        {f.name for f in dataclasses.fields(G.RBFSpec)}
    assert len({g.key for g in G.TOP_GAINS}) == len(G.TOP_GAINS)
    assert len({g.key for g in G.LOOP_GAINS}) == len(G.LOOP_GAINS)


def test_the_kernel_slots_and_their_constants_follow_the_registry():
    assert ck.GAIN_ENTRIES == tuple(g.attr for g in G.TOP_GAINS if g.slot)
    assert ck.LOOP_GAIN_ENTRIES == tuple(g.attr for g in G.LOOP_GAINS if g.slot)
    # one L_* per loop slot and one CP_* per top-level slot, named after it, plain ints (numba's constants)
    loop = {'L_' + re.sub(r'\W', '_', attr).strip('_').upper(): offset for attr, offset in ck.LOOP_GAIN_OFFSET.items()}
    assert {name: getattr(ck, name) for name in vars(ck) if name.startswith('L_')} == loop
    top = {'CP_' + attr.upper(): index for attr, index in ck.GAIN_INDEX.items()}
    assert {name: getattr(ck, name) for name in top} == top
    assert all(type(getattr(ck, name)) is int and name in ck.__all__ for name in (*loop, *top))
    assert ck.CP_INNER == ck.CP_OUTER + ck.LOOP_GAINS_SIZE == ck.CP_OUTER + len(ck.LOOP_GAIN_ENTRIES)


def test_the_gain_parameters_follow_the_registry():
    params = {p.name: p for p in G.gain_parameters(yaml.safe_load(GAINS_FILE.read_text()))}
    for g in G.GAINS:
        for name, loop in ([(g.key, None)] if g.scope == G.TOP else
                           [(f'{loop}.{g.key}', loop) for loop in G.LOOPS if g.applies_to(loop)]):
            if name not in params:          # optional and not in the paper's file
                assert g.default is not None, name
                continue
            p = params[name]
            assert p.description == g.description(loop) and p.read_only == g.read_only, name
            assert p.minimum == (None if g.minimum is None else float(g.minimum)), name
            assert type(p.value) is (int if g.integer else float), name


def _bounds_cases():
    """``(key path, bad value, message)`` of the lower and upper bound of every gain that has one."""
    for g in G.GAINS:
        path = (g.key,) if g.scope == G.TOP else ('inner', g.key)
        shown = '' if g.scope == G.TOP else 'inner: '
        if g.at_most is not None:       # a closed range, said whole: (0, 1]
            allowed = f'{"(" if g.strict else "["}{g.minimum}, {g.at_most}]'
            for bad in (float(g.minimum) - (0.0 if g.strict else 1.0), float(g.at_most) + 0.5):
                yield path, bad, f'{shown}{g.key} must be {allowed}, got {bad!r}'
        elif g.minimum is not None and not g.integer:
            relation = '>' if g.strict else '>='
            bad = float(g.minimum) - (0.0 if g.strict else 1.0)
            yield path, bad, f'{shown}{g.key} must be {relation} {g.minimum}, got {bad!r}'
        if g.below is not None:
            yield path, float(g.below), f'{shown}{g.key} must be < {g.below}, got {float(g.below)!r}'
        if g.integer:
            yield path, 0.5, f'{shown}{g.key} must be an integer >= {g.minimum}, got 0.5'
        yield path, 'x', f'{shown}{g.key} must be {"an integer" if g.integer else "a number"}'


@pytest.mark.parametrize('path, bad, message', list(_bounds_cases()), ids=lambda v: str(v))
def test_a_bad_gain_is_named_with_its_file_line_and_what_is_allowed(path, bad, message):
    text = GAINS_FILE.read_text()
    data, _ = parse_yaml(text, 'g.yaml')
    at = data['/**']['ros__parameters']
    for key in path[:-1]:
        at = at[key]
    at[path[-1]] = bad
    text = yaml.safe_dump(data, sort_keys=False)
    _, lines = parse_yaml(text, 'g.yaml')
    line = lines[('/**', 'ros__parameters') + path]
    with pytest.raises(G.GainsError) as info:
        G.ControllerGains.from_mapping(yaml.safe_load(text), source='g.yaml', lines=lines)
    assert str(info.value).startswith(f'g.yaml:{line}: {message}'), str(info.value)
    assert info.value.keys == path and info.value.line == line


def test_unknown_and_missing_keys_are_named_with_their_line():
    text = GAINS_FILE.read_text().replace('      kappa: 20.0 ', '      kappx: 20.0 ', 1)
    data, lines = parse_yaml(text, 'g.yaml')
    with pytest.raises(G.GainsError, match=r"^g\.yaml:(\d+): outer: unknown key\(s\) \['kappx'\]; allowed: k, r, "
                       r"tau_command, kappa,") as info:
        G.ControllerGains.from_mapping(data, source='g.yaml', lines=lines)
    assert info.value.line == lines[('/**', 'ros__parameters', 'outer', 'kappx')]
    del data['/**']['ros__parameters']['inner']['k']
    data['/**']['ros__parameters']['outer']['kappa'] = data['/**']['ros__parameters']['outer'].pop('kappx')
    with pytest.raises(G.GainsError, match=r"^g\.yaml:\d+: inner: missing key\(s\) \['k'\]$"):
        G.ControllerGains.from_mapping(data, source='g.yaml', lines=lines)


def test_a_scenario_s_gains_file_is_read_for_lines_only_when_an_error_needs_one(tmp_path):
    from uh_topology.scenario import load_scenario
    scenario = load_scenario('paper')
    lines = G._scenario_lines(scenario)
    G.ControllerGains.from_mapping(scenario.gains, source=G.gains_source(scenario), lines=lines)
    assert 'data' not in vars(lines)        # no error: the file was not parsed again
    bad = scenario.gains
    bad['/**']['ros__parameters']['beta'] = 0.0
    with pytest.raises(G.GainsError, match=r'paper_gains\.yaml:\d+: beta must be > 0, got 0\.0'):
        G.ControllerGains.from_mapping(bad, source=G.gains_source(scenario), lines=lines)
    # an error found without lines gets them from the scenario (the node's parameters do this)
    unlocated = pytest.raises(G.GainsError, G.gain_parameters, bad, source=G.gains_source(scenario)).value
    assert unlocated.line is None and G.located(unlocated, scenario).line == lines[('/**', 'ros__parameters', 'beta')]


_DUMMY_PROBE = r'''
import json, yaml
from uh_controller_node import gains as G, control_kernels as ck
from uh_controller_node.nominal_model import nominal_model
from uh_core.airframe import load_helicopter_params
mapping = yaml.safe_load(open({gains_file!r}))
loops = mapping['/**']['ros__parameters']
loops['outer']['dummy'], loops['inner']['dummy'] = 0.25, 0.75
gains = G.ControllerGains.from_mapping(mapping)
params = ck.control_parameters(gains, nominal_model(load_helicopter_params(), 1.0))
errors = []
for value in ('missing', -1.0):
    bad = yaml.safe_load(open({gains_file!r}))
    if value != 'missing':
        bad['/**']['ros__parameters']['outer'].update(dummy=value)
    bad['/**']['ros__parameters']['inner'].update(dummy=0.5)
    try:
        G.ControllerGains.from_mapping(bad, source='g.yaml')
    except G.GainsError as exc:
        errors.append(str(exc))
print(json.dumps(dict(
    file=G.__file__, outer=gains.outer.dummy, inner=gains.inner.dummy, offset=ck.LOOP_GAIN_OFFSET['dummy'],
    size=ck.LOOP_GAINS_SIZE, in_params=[params[ck.CP_OUTER + ck.LOOP_GAIN_OFFSET['dummy']],
                                        params[ck.CP_INNER + ck.LOOP_GAIN_OFFSET['dummy']]],
    late_sigma=[ck.L_LATE_SIGMA, ck.LOOP_GAIN_OFFSET['late_sigma']],
    parameters=[p.name for p in G.gain_parameters(mapping) if p.name.endswith('.dummy')],
    table=[row for row in G.gains_markdown_table(mapping).splitlines() if '`dummy`' in row],
    errors=errors)))
'''


def test_a_gain_declared_once_reaches_the_reader_the_parameter_vector_the_parameters_and_the_docs(tmp_path):
    package = tmp_path / 'uh_controller_node'
    shutil.copytree(ROOT / 'uh_controller_node' / 'uh_controller_node', package,
                    ignore=shutil.ignore_patterns('__pycache__', '*.so'))
    source = (package / 'gains.py').read_text()
    end = next(node.end_lineno for node in ast.parse(source).body
               if isinstance(node, ast.Assign) and any(getattr(t, 'id', '') == 'GAINS' for t in node.targets))
    lines = source.splitlines(keepends=True)
    lines.insert(end - 1, "    Gain('dummy', BOTH, 'a gain declared by a test', symbol='d', unit='s'),\n")
    (package / 'gains.py').write_text(''.join(lines))             # the one edit
    env = dict(os.environ, PYTHONPATH=str(tmp_path), NUMBA_CACHE_DIR=str(tmp_path / 'numba'))
    done = subprocess.run([sys.executable, '-P', '-c', _DUMMY_PROBE.format(gains_file=str(GAINS_FILE))],
                          env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout)
    assert out['file'] == str(package / 'gains.py')
    assert (out['outer'], out['inner']) == (0.25, 0.75) and out['in_params'] == [0.25, 0.75]
    assert out['offset'] == ck.LOOP_GAINS_SIZE and out['size'] == ck.LOOP_GAINS_SIZE + 1
    assert out['late_sigma'][0] == out['late_sigma'][1] == ck.L_LATE_SIGMA      # the others keep their slots
    assert out['parameters'] == ['outer.dummy', 'inner.dummy']
    assert out['table'] == ['| `dummy` | a gain declared by a test | `d`, s | `d`, s | > 0 | 0.25 | 0.75 |']
    assert out['errors'][0] == "g.yaml: outer: missing key(s) ['dummy']"
    assert out['errors'][1] == 'g.yaml: outer: dummy must be > 0, got -1.0'
