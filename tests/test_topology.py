"""Scenario loading and topology validation (docs/graph.md, docs/scenario.md; paper Assumption 1, Lemma 1)."""
import copy
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from uh_controller_node import gains as controller_gains
from uh_core.layout import CHANNEL_ALIASES
from uh_topology import errors as E
from uh_topology import schema
from uh_topology.graph import (
    check_assumption1,
    check_lemma1,
    containment_pattern,
    containment_weights,
    laplacian,
    laplacian_blocks,
    leader_tracking_matrix,
)
from uh_topology.scenario import (
    FaultSpec,
    Scenario,
    bundled_scenarios,
    load_scenario,
    parse_scenario,
    scenario_from_mapping,
)

PAPER = load_scenario('paper')
PAPER_FILE = Path(PAPER.source)


def _base():
    """Give the paper scenario as a plain mapping, with inline gains (independent of the gains file)."""
    data = yaml.safe_load(PAPER_FILE.read_text())
    data['gains'] = {'k1': 1.0}
    return data


def _build(data, tmp_path=None):
    text = yaml.safe_dump(data, sort_keys=False)
    return parse_scenario(text, source='test.yaml', base_dir=tmp_path)


# ------------------------------------------------------------------------------------------------
# The paper scenario


def test_paper_scenario_basics():
    s = PAPER
    assert isinstance(s, Scenario) and s.name == 'paper'
    assert s.leaders == (1, 2, 3) and s.followers == (4, 5) and s.ids == (1, 2, 3, 4, 5)
    assert (s.dt, s.substeps, s.duration, s.settle_time, s.model_mismatch) == (0.01, 5, 60.0, 20.0, 0.9)
    assert s.num_steps == 6000 and s.helicopter == 'helicopter'
    assert s.gains_path is not None and s.gains_path.name == 'paper_gains.yaml'
    assert 'paper' in bundled_scenarios()
    assert load_scenario(PAPER_FILE).name == 'paper'  # by path as well


def test_paper_adjacency_and_neighbours():
    s = PAPER
    # rows: receiver i = 0..5, columns: sender j = 0 (virtual leader), 1..5
    expected = np.zeros((6, 6))
    for i, j in [(1, 0), (2, 1), (3, 2), (1, 3), (4, 1), (4, 2), (4, 5), (5, 3), (5, 4)]:
        expected[i, j] = 1.0
    np.testing.assert_array_equal(s.adjacency, expected)
    assert [s.neighbours(i) for i in s.ids] == [(3,), (1,), (2,), (1, 2, 5), (3, 4)]
    assert [s.leader_link(i) for i in s.ids] == [1.0, 0.0, 0.0, 0.0, 0.0]
    assert [s.degree(i) for i in s.ids] == [2.0, 1.0, 1.0, 3.0, 2.0]  # d_i = sum_j a_ij + a_i0
    assert s.weight(4, 5) == 1.0 and s.weight(5, 1) == 0.0 and s.weight(1, 0) == 1.0
    assert [s.role(i) for i in s.ids] == ['leader'] * 3 + ['follower'] * 2


def test_paper_laplacian_blocks_and_containment_weights():
    l1, l2 = PAPER.laplacian_blocks
    np.testing.assert_array_equal(l1, [[3.0, -1.0], [-1.0, 2.0]])
    np.testing.assert_array_equal(l2, [[-1.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
    # -L1^-1 L2 = (1/5) [[2, 1], [1, 3]] [[1, 1, 0], [0, 0, 1]]; a 2x2 solve is exact to a few ulps
    np.testing.assert_allclose(PAPER.containment_weights, [[0.4, 0.4, 0.2], [0.2, 0.2, 0.6]], rtol=0, atol=1e-15)
    assert PAPER.containment_weight_rows()[5] == pytest.approx({1: 0.2, 2: 0.2, 3: 0.6}, abs=1e-15)
    lap = PAPER.laplacian
    np.testing.assert_allclose(lap.sum(axis=1), 0.0, atol=0)
    assert np.all(np.linalg.eigvals(l1).real > 0)
    assert np.all(np.linalg.eigvals(PAPER.leader_tracking_matrix).real > 0)
    np.testing.assert_array_equal(PAPER.leader_tracking_matrix, [[2, 0, -1], [-1, 1, 0], [0, -1, 1]])


def test_paper_offsets_initial_states_faults_reference():
    s = PAPER
    assert set(s.offsets) == {1, 2, 3}
    for i, h in s.offsets.items():
        angle = 2 * math.pi * (i - 1) / 3
        np.testing.assert_allclose(h, [3 * math.cos(angle), 3 * math.sin(angle), 0.0], atol=1e-15)
    positions = {1: (2, -1, 8), 2: (-3, 2, 9), 3: (-1, -4, 7), 4: (1, 1, 6), 5: (-2, -2, 11)}
    for i, p in positions.items():
        np.testing.assert_array_equal(s.initial_states[i], np.concatenate([p, np.zeros(9)]))
    assert s.faults[1] == () and s.faults[4] == ()
    assert s.faults[2] == (FaultSpec(0, 0.8, 0.0, 0.01, 0.5, 10.0), FaultSpec(2, 0.85, 0.005, 0.0, 0.0, 10.0))
    assert s.faults[3] == (FaultSpec(1, 0.8, 0.01, 0.0, 0.0, 10.0), FaultSpec(3, 0.75, -0.005, 0.0, 0.0, 10.0))
    assert s.faults[5] == (FaultSpec(0, 0.85, -0.01, 0.0, 0.0, 10.0), FaultSpec(2, 0.8, 0.0, 0.005, 0.3, 10.0))
    r = s.reference
    assert (r.radius, r.angular_rate, r.climb_rate, r.yaw_rate, r.initial_yaw) == (10.0, 0.1, 0.1, 0.1, 0.0)
    np.testing.assert_array_equal(r.center, [0.0, 10.0, 10.0])
    d = s.disturbance
    assert not d.is_zero and np.all(d.amplitude <= 0.3) and np.all(d.frequency <= 0.5)


def test_scenario_is_read_only():
    with pytest.raises(ValueError):
        PAPER.adjacency[1, 0] = 2.0
    with pytest.raises(ValueError):
        PAPER.initial_states[1][0] = 5.0
    with pytest.raises(TypeError):
        PAPER.offsets[1] = np.zeros(3)
    with pytest.raises(AttributeError):
        PAPER.dt = 0.1


def test_unknown_id_in_accessors():
    with pytest.raises(E.UnknownIdError, match=r'no UH with id 6; ids are 1..5'):
        PAPER.neighbours(6)
    with pytest.raises(E.UnknownIdError, match=r'no UH with id 0'):
        PAPER.leader_link(0)


# ------------------------------------------------------------------------------------------------
# Gains


def test_inline_gains_and_defaults():
    data = _base()
    for key in ('substeps', 'settle_time', 'model_mismatch', 'helicopter', 'disturbance', 'faults'):
        del data[key]
    s = _build(data)
    assert s.gains == {'k1': 1.0} and s.gains_path is None
    g = s.gains
    g['k1'] = 5.0
    assert s.gains == {'k1': 1.0}  # a copy per access
    assert (s.substeps, s.settle_time, s.model_mismatch, s.helicopter) == (5, 20.0, 0.9, 'helicopter')
    assert s.disturbance.is_zero and all(f == () for f in s.faults.values())


def test_gains_file_relative_to_the_scenario(tmp_path):
    (tmp_path / 'g.yaml').write_text('outer: {k1: 2.0}\n')
    data = _base()
    data['gains'] = 'g.yaml'
    data['helicopter'] = 'airframes/heli.yaml'
    path = tmp_path / 'scen.yaml'
    path.write_text(yaml.safe_dump(data))
    s = load_scenario(path)
    assert s.gains == {'outer': {'k1': 2.0}}
    assert s.gains_path == tmp_path / 'g.yaml'
    assert s.helicopter == str(tmp_path / 'airframes' / 'heli.yaml')


def test_gains_file_errors_are_reported_on_access(tmp_path):
    data = _base()
    data['gains'] = 'missing_gains.yaml'
    s = _build(data, tmp_path)   # the scenario itself is valid; the gains are read lazily
    with pytest.raises(E.GainsFileError, match=r"gains: cannot read the gains file .*missing_gains.yaml"):
        _ = s.gains
    (tmp_path / 'bad.yaml').write_text('k1: [1, 2\n')
    data['gains'] = 'bad.yaml'
    with pytest.raises(E.ScenarioSyntaxError, match=r'bad.yaml:\d+: YAML syntax error'):
        _ = _build(data, tmp_path).gains
    (tmp_path / 'list.yaml').write_text('- 1\n- 2\n')
    data['gains'] = 'list.yaml'
    with pytest.raises(E.GainsFileError, match='must hold a mapping, got list'):
        _ = _build(data, tmp_path).gains
    # the gains file is read with the schema's YAML parse: a repeated key is an error with its line
    (tmp_path / 'twice.yaml').write_text('beta: 2.0\nouter:\n  k: 1.0\nbeta: 3.0\n')
    data['gains'] = 'twice.yaml'
    with pytest.raises(E.DuplicateKeyError, match=r"twice.yaml:4: .*key 'beta' repeated \(first at line 1\)"):
        _ = _build(data, tmp_path).gains


# ------------------------------------------------------------------------------------------------
# Invalid scenarios: each its own error, with what / where / what is allowed


def _edges(data, pairs):
    data['edges'] = [{'uh': i, 'hears': j, 'weight': 1.0} for i, j in pairs]


PAPER_EDGES = [(1, 3), (2, 1), (3, 2), (4, 1), (4, 2), (4, 5), (5, 3), (5, 4)]


def _m_unreachable_leader(d):
    _edges(d, [e for e in PAPER_EDGES if e != (3, 2)])


def _m_unreachable_leader_no_link(d):
    d['reference_links'] = []


def _m_unreachable_follower(d):
    _edges(d, [e for e in PAPER_EDGES if e[0] != 5])


def _m_unreachable_followers_cycle(d):
    _edges(d, [(1, 3), (2, 1), (3, 2), (4, 5), (5, 4)])


def _m_self_loop(d):
    d['edges'].append({'uh': 4, 'hears': 4, 'weight': 1.0})


def _m_negative_weight(d):
    d['edges'][3]['weight'] = -0.5


def _m_negative_link(d):
    d['reference_links'][0]['weight'] = -1.0


def _m_unknown_id_edge(d):
    d['edges'].append({'uh': 4, 'hears': 7})


def _m_virtual_leader_in_edges(d):
    d['edges'].append({'uh': 2, 'hears': 0})


def _m_unknown_id_link(d):
    d['reference_links'].append({'uh': 9})


def _m_unknown_id_fault(d):
    d['faults'][0]['uh'] = 6


def _m_duplicate_id(d):
    d['uhs'][4]['id'] = 4


def _m_follower_linked(d):
    d['reference_links'].append({'uh': 5, 'weight': 0.5})


def _m_missing_offset(d):
    del d['uhs'][1]['offset']


def _m_follower_offset(d):
    d['uhs'][3]['offset'] = [0.0, 0.0, 0.0]


def _m_leader_hears_follower(d):
    d['edges'].append({'uh': 2, 'hears': 4})


def _m_duplicate_edge(d):
    d['edges'].append({'uh': 5, 'hears': 4, 'weight': 2.0})


def _m_duplicate_link(d):
    d['reference_links'].append({'uh': 1, 'weight': 1.0})


def _m_leaders_not_first(d):
    d['uhs'][0]['role'] = 'follower'
    d['uhs'][0].pop('offset')
    d['uhs'][3]['role'] = 'leader'
    d['uhs'][3]['offset'] = [0.0, 0.0, 0.0]


def _m_id_zero(d):
    d['uhs'][4]['id'] = 0


def _m_no_leader(d):
    for u in d['uhs']:
        u['role'] = 'follower'
        u.pop('offset', None)


def _m_duplicate_fault(d):
    d['faults'].append({'uh': 2, 'channel': 0, 'rho': 0.9})


INVALID = {
    'unreachable_leader': (_m_unreachable_leader, E.UnreachableLeaderError,
                           r'uhs\[2\]: no directed path from the virtual leader \(id 0\) to leader\(s\) \[3\]; '
                           r'every leader must hear'),
    'unreachable_leader_no_link': (_m_unreachable_leader_no_link, E.UnreachableLeaderError,
                                   r'leader\(s\) \[1, 2, 3\]'),
    'unreachable_follower': (_m_unreachable_follower, E.UnreachableFollowerError,
                             r'uhs\[4\]: no directed path from any leader to follower\(s\) \[5\]; '
                             r'every follower must hear'),
    'unreachable_followers_cycle': (_m_unreachable_followers_cycle, E.UnreachableFollowerError,
                                    r'follower\(s\) \[4, 5\]'),
    'self_loop': (_m_self_loop, E.SelfLoopError,
                  r'edges\[8\]: UH 4 hears itself \(self-loop\); an edge must join two different UHs'),
    'negative_weight': (_m_negative_weight, E.NegativeWeightError,
                        r'edges\[3\]\.weight: negative weight -0.5 on edge 4<-1; allowed: a weight >= 0'),
    'negative_link': (_m_negative_link, E.NegativeWeightError,
                      r'reference_links\[0\]\.weight: negative weight -1.0 on the virtual-leader link 1<-0'),
    'unknown_id_edge': (_m_unknown_id_edge, E.UnknownIdError,
                        r'edges\[8\]\.hears: UH id 7 is not a UH of this scenario; known ids: \[1, 2, 3, 4, 5\]'),
    'virtual_leader_in_edges': (_m_virtual_leader_in_edges, E.UnknownIdError,
                                r'edges\[8\]\.hears: UH id 0 .*id 0 is the virtual leader: link leaders to it '
                                r'under reference_links'),
    'unknown_id_link': (_m_unknown_id_link, E.UnknownIdError, r'reference_links\[1\]\.uh: UH id 9 is not a UH'),
    'unknown_id_fault': (_m_unknown_id_fault, E.UnknownIdError, r'faults\[0\]\.uh: UH id 6 is not a UH'),
    'duplicate_id': (_m_duplicate_id, E.DuplicateIdError,
                     r'uhs\[4\]\.id: UH id 4 is already used by uhs\[3\]; ids must be unique'),
    'follower_linked': (_m_follower_linked, E.FollowerLinkedToReferenceError,
                        r'reference_links\[1\]\.uh: follower 5 hears the virtual leader; only leaders may'),
    'missing_offset': (_m_missing_offset, E.MissingOffsetError,
                       r'uhs\[1\]: leader 2 has no formation offset; add offset: \[x, y, z\] \(m\)'),
    'follower_offset': (_m_follower_offset, E.FollowerOffsetError,
                        r'uhs\[3\]\.offset: follower 4 has a formation offset; only leaders have offsets'),
    'leader_hears_follower': (_m_leader_hears_follower, E.LeaderHearsFollowerError,
                              r'edges\[8\]: leader 2 hears follower 4; leaders may only hear leaders and the '
                              r'virtual leader'),
    'duplicate_edge': (_m_duplicate_edge, E.DuplicateEdgeError,
                       r'edges\[8\]: edge 5<-4 is already listed as edges\[7\]'),
    'duplicate_link': (_m_duplicate_link, E.DuplicateEdgeError,
                       r'reference_links\[1\]: virtual-leader link 1<-0 is already listed'),
    'leaders_not_first': (_m_leaders_not_first, E.IdNumberingError,
                          r'uhs: ids must be 1..5 with the leaders first; got leaders \[2, 3, 4\]'),
    'id_zero': (_m_id_zero, E.IdNumberingError, r'uhs\[4\]\.id: UH id 0 is not allowed; 0 is the virtual leader'),
    'no_leader': (_m_no_leader, E.IdNumberingError, r'no leader; at least one UH must have role: leader'),
    'duplicate_fault': (_m_duplicate_fault, E.DuplicateFaultError,
                        r'faults\[6\]\.channel: UH 2 channel 0 already has a fault \(faults\[0\]\)'),
}


@pytest.mark.parametrize('case', sorted(INVALID))
def test_invalid_topology_raises_its_own_error(case):
    mutate, cls, message = INVALID[case]
    data = _base()
    mutate(data)
    with pytest.raises(cls, match=message) as info:
        _build(data)
    assert type(info.value) is cls           # the specific class, not just a base
    assert isinstance(info.value, E.ScenarioError) and isinstance(info.value, ValueError)
    assert str(info.value).startswith('test.yaml:')  # where: the source file and line
    assert info.value.line is not None


def test_unreachable_errors_name_the_ids():
    data = _base()
    _m_unreachable_followers_cycle(data)
    with pytest.raises(E.UnreachableFollowerError) as info:
        _build(data)
    assert info.value.ids == (4, 5)


def _set(path, value):
    def mutate(d):
        node = d
        for key in path[:-1]:
            node = node[key]
        if value is _DELETE:
            del node[path[-1]]
        else:
            node[path[-1]] = value
    return mutate


_DELETE = object()

SCHEMA = {
    'unknown_top_key': (_set(('edgez',), []), E.UnknownKeyError,
                        r"edgez: unknown key 'edgez'; allowed keys here: name, dt, duration"),
    'unknown_nested_key': (_set(('edges', 0, 'wieght'), 1.0), E.UnknownKeyError,
                           r"edges\[0\]\.wieght: unknown key 'wieght'; allowed keys here: uh, hears, weight"),
    'missing_top_field': (_set(('dt',), _DELETE), E.MissingFieldError, r"missing required key 'dt'"),
    'missing_role': (_set(('uhs', 2, 'role'), _DELETE), E.MissingFieldError,
                     r"uhs\[2\]: missing required key 'role' \(required: id, role, initial_state\)"),
    'missing_position': (_set(('uhs', 0, 'initial_state', 'position'), _DELETE), E.MissingFieldError,
                         r"uhs\[0\]\.initial_state: missing required key 'position'"),
    'wrong_type_dt': (_set(('dt',), 'fast'), E.WrongTypeError, r"dt: expected a number \(s\), got str 'fast'"),
    'wrong_type_bool': (_set(('duration',), True), E.WrongTypeError, r'duration: expected a number \(s\), got bool'),
    'wrong_type_position': (_set(('uhs', 1, 'initial_state', 'position'), [1.0, 2.0]), E.WrongTypeError,
                            r'uhs\[1\]\.initial_state\.position: expected a list of 3 numbers \(m\)'),
    'wrong_type_edges': (_set(('edges',), {'uh': 1}), E.WrongTypeError, r'edges: expected a list of edges, got dict'),
    'wrong_type_substeps': (_set(('substeps',), 2.5), E.WrongTypeError, r'substeps: expected an integer'),
    'wrong_type_id': (_set(('uhs', 0, 'id'), 'one'), E.WrongTypeError, r'uhs\[0\]\.id: expected an integer UH id'),
    'wrong_type_gains': (_set(('gains',), 3), E.WrongTypeError, r'gains: expected a file name'),
    'non_finite_nan': (_set(('reference', 'radius'), float('nan')), E.NonFiniteError,
                       r'reference\.radius: expected a finite number \(m\), got nan'),
    'non_finite_inf': (_set(('uhs', 3, 'initial_state', 'position', 2), float('inf')), E.NonFiniteError,
                       r'uhs\[3\]\.initial_state\.position\[2\]: expected a finite number'),
    'non_finite_weight': (_set(('edges', 2, 'weight'), float('-inf')), E.NonFiniteError,
                          r'edges\[2\]\.weight: expected a finite number, got -inf'),
    'bad_dt': (_set(('dt',), -0.01), E.InvalidValueError, r'dt: value -0.01 out of range; allowed: > 0.0 \(s\)'),
    'bad_substeps': (_set(('substeps',), 0), E.InvalidValueError, r'substeps: value 0 out of range; allowed: >= 1'),
    'bad_duration_multiple': (_set(('duration',), 60.005), E.InvalidValueError,
                              r'duration 60.005 s is not a whole number of control periods dt = 0.01 s'),
    'bad_settle': (_set(('settle_time',), 60.0), E.InvalidValueError,
                   r'settle_time: value 60.0 out of range; allowed: \[0.0, 60.0\) \(s\)'),
    'bad_role': (_set(('uhs', 0, 'role'), 'boss'), E.InvalidValueError,
                 r"uhs\[0\]\.role: 'boss' is not allowed; allowed: leader, follower"),
    'bad_rho': (_set(('faults', 1, 'rho'), 1.5), E.InvalidValueError,
                r'faults\[1\]\.rho: value 1.5 out of range; allowed: \[0.0, 1.0\]'),
    'bad_channel_name': (_set(('faults', 1, 'channel'), 'aileron'), E.InvalidValueError,
                         r"faults\[1\]\.channel: unknown channel 'aileron'; allowed: 0..3 or collective"),
    'bad_channel_index': (_set(('faults', 1, 'channel'), 4), E.InvalidValueError,
                          r'faults\[1\]\.channel: channel 4 out of range; allowed: 0..3'),
    'bad_onset': (_set(('faults', 0, 'onset_time'), -2.0), E.InvalidValueError,
                  r'faults\[0\]\.onset_time: value -2.0 out of range; allowed: >= 0.0 \(s\)'),
    'bad_pitch': (_set(('uhs', 0, 'initial_state', 'euler'), [0.0, 1.6, 0.0]), E.InvalidValueError,
                  r'uhs\[0\]\.initial_state\.euler\[1\]: pitch 1.6 rad; allowed: \|angle\| < pi/2'),
    'bad_disturbance': (_set(('disturbance', 'amplitude'), [-0.1, 0.0, 0.0]), E.InvalidValueError,
                        r'disturbance\.amplitude: negative amplitude'),
    'bad_mismatch': (_set(('model_mismatch',), 0.0), E.InvalidValueError,
                     r'model_mismatch: value 0.0 out of range; allowed: > 0.0'),
    'not_a_mapping': (lambda d: d.__setitem__('reference', [1, 2]), E.WrongTypeError,
                      r'reference: expected a reference mapping, got list'),
}


@pytest.mark.parametrize('case', sorted(SCHEMA))
def test_invalid_schema_raises_its_own_error(case):
    mutate, cls, message = SCHEMA[case]
    data = _base()
    mutate(data)
    with pytest.raises(cls, match=message) as info:
        _build(data)
    assert type(info.value) is cls and isinstance(info.value, E.SchemaError)


# ------------------------------------------------------------------------------------------------
# File-level errors and line numbers


def test_yaml_syntax_error_names_the_line(tmp_path):
    lines = PAPER_FILE.read_text().splitlines()
    idx = next(i for i, line in enumerate(lines) if line.startswith('  - {uh: 4, hears: 2'))
    lines[idx] = '  - {uh: 4, hears: 2, weight: 1.0'   # unclosed flow mapping
    path = tmp_path / 'broken.yaml'
    path.write_text('\n'.join(lines) + '\n')
    with pytest.raises(E.ScenarioSyntaxError, match=r'broken.yaml:\d+: YAML syntax error') as info:
        load_scenario(path)
    # the parser notices at the next line at the latest
    assert info.value.line in (idx + 1, idx + 2)


def test_semantic_errors_carry_the_line_of_the_key(tmp_path):
    text = PAPER_FILE.read_text()
    old = '  - {uh: 4, hears: 5, weight: 1.0}'
    assert old in text
    text = text.replace(old, '  - {uh: 4, hears: 5, weight: -2.0}')
    path = tmp_path / 'neg.yaml'
    path.write_text(text)
    line = 1 + next(i for i, s in enumerate(text.splitlines()) if 'weight: -2.0' in s)
    with pytest.raises(E.NegativeWeightError) as info:
        load_scenario(path)
    assert info.value.line == line and info.value.path == 'edges[5].weight'
    assert str(info.value).startswith(f'{path}:{line}: edges[5].weight: negative weight -2.0 on edge 4<-5')


def test_duplicate_yaml_key_is_rejected():
    text = 'name: a\ndt: 0.01\ndt: 0.02\n'
    with pytest.raises(E.DuplicateKeyError, match=r"x.yaml:3: key 'dt' repeated \(first at line 2\)"):
        parse_scenario(text, source='x.yaml')


def test_empty_or_non_mapping_documents():
    with pytest.raises(E.MissingFieldError, match='the scenario is empty'):
        parse_scenario('', source='e.yaml')
    with pytest.raises(E.WrongTypeError, match='expected a scenario mapping, got list'):
        parse_scenario('- 1\n', source='l.yaml')


def test_unknown_scenario_name():
    with pytest.raises(E.ScenarioNotFoundError, match=r"no scenario file 'papr'.*bundled name \(crowd, paper, "):
        load_scenario('papr')


def test_mapping_entry_point_without_source():
    data = _base()
    s = scenario_from_mapping(data)
    assert s.source is None and s.containment_weights.shape == (2, 3)
    data['dt'] = 0
    with pytest.raises(E.InvalidValueError, match=r'^dt: value 0.0 out of range'):
        scenario_from_mapping(data)


# ------------------------------------------------------------------------------------------------
# Graph maths: properties on random graphs, Lemma 1 checks


def _random_topology(rng, n_leaders, n_followers):
    """Random weighted graph satisfying Assumption 1 (a spanning tree plus random extra edges)."""
    n = n_leaders + n_followers
    a = np.zeros((n + 1, n + 1))
    leaders = list(range(1, n_leaders + 1))
    followers = list(range(n_leaders + 1, n + 1))
    a[1, 0] = rng.uniform(0.5, 2.0)
    for i in leaders[1:]:
        a[i, rng.integers(1, i)] = rng.uniform(0.5, 2.0)        # tree among leaders
        if rng.random() < 0.3:
            a[i, 0] = rng.uniform(0.5, 2.0)
    for k in followers:
        a[k, rng.integers(1, k)] = rng.uniform(0.5, 2.0)        # tree: hears an earlier UH
    for _ in range(n):
        i, j = rng.integers(1, n + 1, size=2)
        if i != j and not (i in leaders and j in followers):
            a[i, j] = rng.uniform(0.1, 2.0)
    return a, leaders, followers


@pytest.mark.parametrize('seed', range(12))
def test_containment_weights_are_convex_on_random_graphs(seed):
    rng = np.random.default_rng(seed)
    a, leaders, followers = _random_topology(rng, int(rng.integers(1, 5)), int(rng.integers(1, 6)))
    check_assumption1(a, leaders, followers)
    l1, l2 = laplacian_blocks(a, leaders, followers)
    pattern = containment_pattern(a, leaders, followers)
    w = check_lemma1(l1, l2, pattern)
    # definition: L1 W + L2 = 0; rows of L sum to zero, so rows of W sum to one
    np.testing.assert_allclose(l1 @ w + l2, 0.0, atol=1e-12)
    np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-12)
    # zero entries come out as +-1e-16 from the solve
    assert np.all(w >= -1e-12) and np.all(pattern.any(axis=1))
    np.testing.assert_array_equal(w > 1e-12, pattern)
    assert np.all(np.linalg.eigvals(leader_tracking_matrix(a, leaders)).real > 0)
    # the followers' consensus x' = -(L1 x + L2 p_L) settles at W p_L (containment target)
    p_l = rng.normal(size=(len(leaders), 3))
    x = np.zeros((len(followers), 3))
    step = 0.5 / np.max(np.abs(np.diag(l1)))
    for _ in range(4000):
        x = x - step * (l1 @ x + l2 @ p_l)
    np.testing.assert_allclose(x, w @ p_l, atol=1e-6)


def test_laplacian_rows_sum_to_zero_and_ignore_the_virtual_leader():
    a = np.array(PAPER.adjacency)
    lap = laplacian(a)
    np.testing.assert_array_equal(lap.sum(axis=1), 0.0)
    np.testing.assert_array_equal(np.diag(lap), [1, 1, 1, 3, 2])
    assert containment_weights(np.zeros((0, 0)), np.zeros((0, 3))).shape == (0, 3)


@pytest.mark.parametrize('l1, l2, pattern, message', [
    ([[-1.0, 0.0], [0.0, 2.0]], [[1.0, 0.0], [0.0, -2.0]], None,
     r'L1 \(follower block of the Laplacian\) has eigenvalue\(s\) with non-positive real part \[-1.0\]'),
    ([[1.0, 0.0], [0.0, 1.0]], [[-2.0, 1.0], [0.0, -1.0]], None, r'-L1\^-1 L2 has negative entries'),
    ([[2.0, 0.0], [0.0, 1.0]], [[-1.0, 0.0], [0.0, -1.0]], None, r'rows of -L1\^-1 L2 sum to \[0.5, 1.0\]'),
    ([[1.0, 0.0], [0.0, 1.0]], [[-1.0, 0.0], [0.0, -1.0]], [[True, True], [False, True]],
     r'positive entries exactly where a leader reaches a follower'),
])
def test_lemma1_violations_raise_laplacian_condition_error(l1, l2, pattern, message):
    with pytest.raises(E.LaplacianConditionError, match=message):
        check_lemma1(np.array(l1), np.array(l2), pattern)


def test_base_mapping_is_valid():
    """Guard for the mutation tests: the unmodified base builds and equals the bundled scenario."""
    s = _build(copy.deepcopy(_base()))
    np.testing.assert_array_equal(s.adjacency, PAPER.adjacency)
    np.testing.assert_array_equal(s.containment_weights, PAPER.containment_weights)


def test_single_leader_without_followers():
    s = parse_scenario('''
name: solo
dt: 0.01
duration: 1.0
settle_time: 0.5
uhs:
  - {id: 1, role: leader, offset: [0, 0, 0], initial_state: {position: [0, 0, 1]}}
edges: []
reference_links: [{uh: 1}]
reference: {radius: 0, angular_rate: 0, center: [0, 0, 1], climb_rate: 0, yaw_rate: 0}
''', source='solo.yaml')
    assert s.leaders == (1,) and s.followers == () and s.neighbours(1) == ()
    assert s.containment_weights.shape == (0, 1) and s.degree(1) == 1.0 and s.gains == {}


def test_zero_weight_edge_is_no_link():
    data = _base()
    data['edges'].append({'uh': 2, 'hears': 3, 'weight': 0.0})
    data['edges'].append({'uh': 3, 'hears': 4, 'weight': 0.0})   # leader <- follower with weight 0
    s = _build(data)
    assert s.neighbours(2) == (1,) and s.neighbours(3) == (2,)
    np.testing.assert_array_equal(s.adjacency, PAPER.adjacency)


def test_every_configuration_error_derives_from_the_schema_base():
    for name in E.__all__:
        assert issubclass(getattr(E, name), schema.ConfigError), name
    # gains content is the controller's concern, the gains file the scenario's: both are scenario errors
    assert issubclass(controller_gains.GainsError, E.ScenarioError) and not hasattr(E, 'GainsError')
    assert issubclass(E.GainsFileError, E.ScenarioError)


def test_the_schema_reads_with_file_line_and_key():
    data, lines = schema.parse_yaml('a:\n  b: [1, 2]\n  c: lateral\n', 'x.yaml')
    ctx = schema.ConfigContext('x.yaml', lines)
    assert ctx.channel(data['a']['c'], ('a', 'c')) == CHANNEL_ALIASES['lateral']
    with pytest.raises(E.WrongTypeError, match=r"^x.yaml:2: a.b: expected a list of 3 numbers \(m\), got list"):
        ctx.vector(data['a']['b'], ('a', 'b'), unit='m')
    with pytest.raises(E.InvalidValueError, match=r'^x.yaml:2: a.b\[1\]: value 2.0 out of range; allowed: \[0, 1\)$'):
        ctx.number(data['a']['b'][1], ('a', 'b', 1), lo=0, hi=1, hi_open=True)
    assert schema.format_key_path(('edges', 3, 'weight')) == 'edges[3].weight'
