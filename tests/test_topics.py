"""The topic registry: names, QoS rules, and the documentation table that mirrors it."""
from pathlib import Path

import pytest

from uh_topology.scenario import load_scenario
from uh_wire import topics as T

ROOT = Path(__file__).resolve().parents[1]


def test_names_resolve_in_the_uh_namespace():
    assert T.uh_topic(3, T.STATE) == '/uh3/state'
    assert T.uh_topic(3, T.REFERENCE) == '/reference'
    assert all(not spec.name.startswith('/') for spec in T.PER_UH)  # relative: __ns:= and remaps work


def test_recorder_lag_fits_in_the_history():
    # the lockstep clock lets the recorder lag RECORDER_LAG_STEPS; the writers must still hold them
    assert T.RECORDER_LAG_STEPS < T.STEP_DEPTH
    assert all(spec.qos.depth == T.STEP_DEPTH and spec.qos.durability == 'transient_local'
               for spec in (*T.TEAM, *T.PER_UH) if spec.per_step)


def test_team_topics_of_the_paper_scenario():
    names = [name for name, _ in T.team_topics(load_scenario('paper').ids)]
    assert len(names) == len(set(names)) == len(T.TEAM) + 5 * len(T.PER_UH)
    assert '/uh5/fault_truth' in names and '/clock' in names


@pytest.mark.parametrize('spec', [*T.TEAM, *T.PER_UH, *T.IMPAIRED_PER_UH, *T.SAFETY_PER_UH, T.MARKERS,
                                  T.RECORDER_PROGRESS],
                         ids=lambda s: s.name)
def test_docs_table_matches_the_registry(spec):
    doc = (ROOT / 'docs' / 'topics.md').read_text()
    name = spec.name if spec.name.startswith('/') else f'/uhN/{spec.name}'
    q = spec.qos
    row = f'| `{name}` | `{spec.type}` | {q.reliability}, {q.history} {q.depth}, {q.durability} |'
    assert row in doc


def test_run_topics_are_what_the_recorder_must_have_subscribed_to_before_step_0():
    """The lockstep clock's list: the team topics, the views unless switched off, /markers with the visualisation."""
    ids = load_scenario('paper').ids
    full = {name for name, _ in T.run_topics(ids)}
    assert full == {name for name, _ in T.team_topics(ids)} | {'/markers'}
    assert {'/tf', '/diagnostics', '/uh4/odom', '/uh1/state', '/clock'} <= full
    bare = {name for name, _ in T.run_topics(ids, views=False, visualization=False)}
    assert bare == full - {'/tf', '/diagnostics', '/markers'} - {f'/uh{i}/odom' for i in ids}
    assert '/uh2/received' in {name for name, _ in T.run_topics(ids, impaired=True)}
    # every topic the recorder must have in time keeps the samples of a late match (docs/architecture.md)
    for _, spec in T.run_topics(ids, impaired=True):
        if spec is not T.FAULT:
            assert spec.qos.durability == 'transient_local', spec.name
