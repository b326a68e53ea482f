"""Deterministic communication and sensing impairments (docs/campaigns.md#impairments).

The hash they draw from, the delivered step, the noise, the scenario's `impairments` key, and the same
received states in the in-process kernel, the object loop and the lockstep distributed stack.
"""
from pathlib import Path

import numpy as np
import pytest
from scenario_texts import paper_yaml

from uh_controller_node.impairments import (
    LOSS_STREAM,
    ReceivedStates,
    add_noise,
    delivered_step,
    hash_uniform,
    reference_hash,
)
from uh_team.team_simulation import run_team_simulation
from uh_topology import errors as E
from uh_topology.scenario import NO_DROPOUT, load_scenario, parse_scenario

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / 'uh_topology' / 'uh_topology' / 'config'
IMPAIRED = ROOT / 'tests' / 'data' / 'paper_impaired.yaml'



@pytest.fixture(scope='module')
def impaired():
    return parse_scenario(paper_yaml(IMPAIRED.read_text()), source='paper_impaired')


# -- the hash, the delivered step and the noise ------------------------------------------------------

def test_the_kernel_hash_is_splitmix64_as_specified_in_plain_integers():
    rng = np.random.default_rng(1)
    for seed, receiver, sender, step, stream in rng.integers(0, 2 ** 31, size=(200, 5)):
        args = tuple(int(v) for v in (seed, receiver, sender, step, stream))
        assert hash_uniform(*args) == reference_hash(*args)
    assert hash_uniform(0, 0, 0, 0, 0) != hash_uniform(0, 0, 0, 1, 0)


def test_loss_draws_are_uniform_enough_to_give_the_requested_rate():
    draws = np.array([hash_uniform(7, 4, 1, s, LOSS_STREAM) for s in range(20000)])
    # 20000 Bernoulli(0.25) draws: the standard error of the rate is 0.003; 0.015 is five of them
    assert abs(np.mean(draws < 0.25) - 0.25) < 0.015
    assert 0.0 <= draws.min() and draws.max() < 1.0


def test_delivered_step_without_loss_is_the_delayed_step_from_the_initial_state_on():
    assert [delivered_step(k, 3, 0, 0.0, NO_DROPOUT, 0, 2, 1) for k in range(6)] == [0, 0, 0, 0, 1, 2]
    assert [delivered_step(k, 0, 0, 0.0, NO_DROPOUT, 0, 2, 1) for k in range(4)] == [0, 1, 2, 3]


def test_delivered_step_is_the_newest_state_not_lost_and_never_goes_back():
    seed, receiver, sender, delay, loss = 5, 4, 1, 2, 0.4
    lost = [hash_uniform(seed, receiver, sender, s, LOSS_STREAM) < loss for s in range(400)]
    steps = [delivered_step(k, delay, 0, loss, NO_DROPOUT, seed, receiver, sender) for k in range(400)]
    for k, s in enumerate(steps):
        newest = k - delay
        expected = max([t for t in range(1, max(newest, 0) + 1) if not lost[t]], default=0)
        assert s == expected, k
    assert all(b >= a for a, b in zip(steps, steps[1:], strict=False))
    assert 0.3 < np.mean(lost) < 0.5   # the draw is the one used (400 draws: std 0.025)


def test_a_dropped_out_sender_is_heard_up_to_the_step_before_its_dropout():
    assert [delivered_step(k, 0, 0, 0.0, 3, 0, 2, 1) for k in range(6)] == [0, 1, 2, 2, 2, 2]
    assert delivered_step(50, 0, 0, 0.0, 0, 0, 2, 1) == 0   # dropped at t = 0: only the initial state


def test_noise_has_the_requested_spread_is_zero_where_asked_and_repeats_for_a_kept_state():
    sigma = np.array([0.5] * 3 + [0.0] * 9)
    state = np.arange(12.0)
    samples = np.empty((4000, 12))
    for s in range(4000):
        add_noise(state, sigma, 3, 1, 2, s, samples[s])
    assert np.array_equal(samples[:, 3:], np.broadcast_to(state[3:], (4000, 9)))
    noise = samples[:, :3] - state[:3]
    # 4000 samples: std of the mean 0.008, of the standard deviation about 0.006
    assert np.all(np.abs(noise.mean(axis=0)) < 0.04) and np.all(np.abs(noise.std(axis=0) - 0.5) < 0.03)
    again = np.empty(12)
    add_noise(state, sigma, 3, 1, 2, 17, again)
    assert np.array_equal(again, samples[17])


def test_received_states_keep_only_what_a_later_step_may_deliver(impaired):
    received = ReceivedStates(4, (1, 2, 5), impaired.impairments, impaired.dt)
    for k in range(400):
        received.receive(k, np.zeros(12), {j: np.full(12, float(k)) for j in (1, 2, 5)})
    assert all(len(h) < 40 for h in received.history.values())   # not all 400 steps
    assert received.sample_steps[5] < impaired.impairments.drop_step(5, impaired.dt)


# -- the scenario key --------------------------------------------------------------------------------

def test_the_scenario_reads_per_link_values_noise_and_dropouts(impaired):
    imp = impaired.impairments
    assert imp.seed == 11 and imp.is_active
    assert imp.delays[(4, 1)] == 7 and imp.losses[(4, 1)] == 0.5
    assert imp.delays[(2, 1)] == 0 and imp.losses[(2, 1)] == 0.0
    assert imp.delays[(5, 3)] == 3 and imp.losses[(5, 3)] == 0.25
    assert set(imp.delays) == {(i, j) for i in impaired.ids for j in impaired.neighbours(i)}
    assert imp.noise.tolist() == [0.02] * 3 + [0.01] * 3 + [0.002] * 6
    assert imp.drop_step(5, impaired.dt) == 150 and imp.drop_step(1, impaired.dt) == NO_DROPOUT
    assert load_scenario('paper').impairments is None


@pytest.mark.parametrize('block, error, where, words', [
    ('impairments: {delay_steps: -1}', E.InvalidValueError, 'impairments.delay_steps', '>= 0'),
    ('impairments: {loss: 1.0}', E.InvalidValueError, 'impairments.loss', '[0.0, 1.0)'),
    ('impairments: {jitter: 2}', E.UnknownKeyError, 'impairments.jitter', 'allowed keys'),
    ('impairments:\n  links:\n    - {uh: 1, hears: 2, delay_steps: 3}', E.InvalidValueError,
     'impairments.links[0]', 'does not hear UH 2'),
    ('impairments: {noise: {position: -0.1}}', E.InvalidValueError, 'impairments.noise.position', '>= 0'),
    ('impairments:\n  dropouts:\n    - {uh: 3, time: 99}', E.InvalidValueError, 'impairments.dropouts[0].time',
     '[0.0, 60.0]'),
])
def test_bad_impairments_are_refused_with_line_and_key(block, error, where, words):
    text = paper_yaml(block)
    with pytest.raises(error) as info:
        parse_scenario(text, source='bad.yaml')
    message = str(info.value)
    first_line = len(text.splitlines()) - len(block.splitlines()) + 1
    assert where in message and words in message and 'bad.yaml' in message
    assert info.value.line >= first_line, message


# -- the same received states everywhere -------------------------------------------------------------

def test_zero_impairments_are_the_run_without_impairments():
    plain = run_team_simulation(load_scenario('paper'), 'proposed', duration=2.0)
    zero_scenario = parse_scenario(paper_yaml('impairments: {seed: 4, delay_steps: 0, loss: 0.0}'), source='zero')
    assert zero_scenario.impairments is None   # so any clock runs it, and nothing extra is published
    zero = run_team_simulation(zero_scenario, 'proposed', duration=2.0)
    assert np.array_equal(plain.states, zero.states) and np.array_equal(plain.commands, zero.commands)


@pytest.mark.parametrize('block', [
    'impairments:\n  dropouts:\n    - {uh: 1, time: 0.0}',     # only the initial state of UH 1, ever
    'impairments: {delay_steps: 500}',                          # longer than the run: initial states only
])
def test_edge_cases_receive_the_same_states_in_the_kernel_and_the_object_loop(block):
    scenario = parse_scenario(paper_yaml(block), source='edge')
    kernel = run_team_simulation(scenario, 'proposed', duration=0.5)
    objects = run_team_simulation(scenario, 'proposed', duration=0.5, engine='objects')
    assert np.array_equal(kernel.states, objects.states) and np.array_equal(kernel.commands, objects.commands)
    received = ReceivedStates(2, (1,), scenario.impairments, scenario.dt)
    initial = np.arange(12.0)
    for k in range(60):
        received.receive(k, np.zeros(12), {1: initial + k})
        assert np.array_equal(received.delivered[1], initial) and received.sample_steps[1] == 0


def test_the_kernel_and_the_object_loop_receive_the_same_states(impaired):
    kernel = run_team_simulation(impaired, 'proposed', duration=3.0)
    objects = run_team_simulation(impaired, 'proposed', duration=3.0, engine='objects')
    for key in kernel.ARRAY_KEYS:
        assert np.array_equal(getattr(kernel, key), getattr(objects, key)), key
    plain = run_team_simulation(load_scenario('paper'), 'proposed', duration=3.0)
    assert not np.array_equal(kernel.commands[1], plain.commands[1])   # the noise acts from step 0
    # UH 5 drops out at 1.5 s: its followers' views of it freeze, so the runs part ways
    assert np.abs(kernel.states[-1] - plain.states[-1]).max() > 0.01


@pytest.mark.dds
@pytest.mark.slow
def test_a_lockstep_distributed_run_with_impairments_equals_the_in_process_run(tmp_path, impaired):
    """Check that a lockstep distributed run with impairments equals the in-process run.

    Delay, loss, noise and a dropout act in each receiving controller node with the functions the
    kernel calls, so the bag equals the in-process run to the bit, and its /uhN/received holds
    exactly the states each controller used.
    """
    from rosbags.rosbag2 import Reader
    from team_runs import assert_lockstep_run_equals_in_process

    from uh_runtime.messages import typestore

    out, reference = assert_lockstep_run_equals_in_process(tmp_path, impaired, paper_yaml(IMPAIRED.read_text()))

    store, received = typestore(), {}
    with Reader(out / 'bag') as reader:
        connections = [c for c in reader.connections if c.topic == '/uh4/received']
        for conn, _, raw in reader.messages(connections=connections):
            msg = store.deserialize_cdr(raw, conn.msgtype)
            received[msg.step] = msg
    assert sorted(received) == list(range(301))
    imp, col = impaired.impairments, {i: c for c, i in enumerate(impaired.ids)}
    expected = np.empty(12)
    for k in (0, 1, 40, 160, 300):
        msg = received[k]
        assert [s.uh_id for s in msg.states] == [4, 1, 2, 5]
        add_noise(reference.states[k, col[4]], imp.noise, imp.seed, 4, 4, k, expected)
        assert _vector(msg.states[0]) == expected.tolist() and msg.states[0].step == k
        for state in msg.states[1:]:
            j = state.uh_id
            s = delivered_step(k, imp.delays[(4, j)], imp.jitters[(4, j)], imp.losses[(4, j)],
                               imp.drop_step(j, impaired.dt), imp.seed, 4, j)
            add_noise(reference.states[s, col[j]], imp.noise, imp.seed, 4, j, s, expected)
            assert state.step == s and _vector(state) == expected.tolist(), (k, j)
    assert received[300].states[3].step < 150   # UH 5 dropped out at step 150


def _vector(state) -> list:
    return [getattr(getattr(state, f), a) for f in ('position', 'velocity', 'euler', 'body_rates')
            for a in 'xyz']
