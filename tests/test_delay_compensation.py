"""Delay compensation and link jitter (docs/delay.md, docs/campaigns.md#impairments).

The prediction of a delayed state, the jitter draws and the order in which states are used, the
scenario keys and their bad values, and the same numbers in the in-process kernel, the object loop
and a lockstep distributed run.
"""
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from scenario_texts import paper_yaml

from uh_bringup import run_formation
from uh_controller_node.impairments import (
    JITTER_STREAM,
    LOSS_STREAM,
    PREDICTION_MARGIN,
    ReceivedStates,
    add_noise,
    arrival_extra,
    delivered_step,
    predict_state,
    prediction_age,
    reference_hash,
)
from uh_core.layout import STATE_SIZE, X_P, X_V
from uh_team.team_simulation import run_team_simulation
from uh_topology import errors as E
from uh_topology.scenario import DEFAULT_COMPENSATION, NO_DROPOUT, parse_scenario
from uh_wire.run_config import DEFAULT_STALE_TIMEOUT

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / 'uh_topology' / 'uh_topology' / 'config'
IMPAIRED = ROOT / 'tests' / 'data' / 'paper_impaired.yaml'
DT = 0.01
EPS = np.finfo(float).eps



def _jittered(compensation: str) -> str:
    """Give the impairments of tests/data/paper_impaired.yaml with jitter on every link and one override."""
    text = IMPAIRED.read_text().replace('  delay_steps: 3\n', f'  delay_steps: 3\n  jitter_steps: 4\n'
                                        f'  delay_compensation: {compensation}\n')
    return text.replace('{uh: 4, hears: 1, delay_steps: 7, loss: 0.5}',
                        '{uh: 4, hears: 1, delay_steps: 7, jitter_steps: 9, loss: 0.5}')


def _state_at(t, p0, v0, a):
    """Make the state at time ``t`` s of a point moving with constant acceleration ``a`` (m/s^2) from p0, v0."""
    x = np.zeros(STATE_SIZE)
    x[X_P:X_P + 3] = p0 + v0 * t + 0.5 * a * t * t
    x[X_V:X_V + 3] = v0 + a * t
    x[6:] = [0.1, -0.2, 1.3, 0.01, 0.02, 0.03]   # attitude and rates: copied, whatever they are
    return x


# -- the prediction ----------------------------------------------------------------------------------

@pytest.mark.parametrize('age', [1, 2, 5, 20])
def test_prediction_removes_the_lag_of_a_constant_velocity_neighbour_exactly(age):
    p0, v = np.array([12.0, -3.5, 8.0]), np.array([1.0, -0.7, 0.1])
    k = 1000
    sent, now = (_state_at(s * DT, p0, v, np.zeros(3)) for s in (k - age, k))
    out = np.empty(STATE_SIZE)
    predict_state(sent, age, DT, out)
    # the prediction p_s + v tau and the direct p0 + v k dt are each three roundings of numbers no
    # larger than `scale` (a relative eps / 2 each); 16 eps scale (~4e-14 m here) bounds their
    # difference with room to spare, while the lag the prediction removes, |v| age dt, is >= 0.01 m
    scale = np.abs(now[X_P:X_P + 3]).max() + np.abs(v).max() * k * DT
    assert np.abs(out - now).max() <= 16 * EPS * scale
    assert np.abs(sent[X_P:X_P + 3] - now[X_P:X_P + 3]).max() > 1e9 * 16 * EPS * scale   # the lag is there
    assert np.array_equal(out[X_V:], sent[X_V:])   # velocity, attitude and rates as received


def test_what_remains_for_an_accelerating_neighbour_is_half_a_tau_squared():
    p0, v0, a = np.array([3.0, 4.0, 10.0]), np.array([0.5, -1.0, 0.1]), np.array([-0.1, 0.05, 0.02])
    k, age = 500, 10
    sent, now = (_state_at(s * DT, p0, v0, a) for s in (k - age, k))
    out = np.empty(STATE_SIZE)
    predict_state(sent, age, DT, out)
    # exactly -a tau^2 / 2 in real numbers; the floats carry ~1e-14 m of rounding on a remainder of up to 5e-4 m
    assert np.allclose(out[X_P:X_P + 3] - now[X_P:X_P + 3], -0.5 * a * (age * DT) ** 2, rtol=1e-6, atol=0.0)


def test_a_state_of_the_current_step_is_used_bit_for_bit_as_received():
    state = np.array([-0.0, np.nan, 1e300, np.inf, -np.inf, 5e-324, 1.0, -0.0, 2.0, 3.0, np.nan, -1.5])
    out = np.full(STATE_SIZE, 7.0)
    predict_state(state, 0, DT, out)
    assert out.tobytes() == state.tobytes()   # -0.0 stays -0.0, NaN stays that NaN


def test_the_prediction_horizon_is_the_links_delay_and_jitter_plus_the_stale_timeout():
    assert PREDICTION_MARGIN == DEFAULT_STALE_TIMEOUT   # the realtime stale timeout, kept as a literal for numba
    margin = round(PREDICTION_MARGIN / DT)
    assert prediction_age(100, 97, 3, 0, DT) == 3
    assert prediction_age(1000, 10, 3, 4, DT) == 3 + 4 + margin   # a sender that dropped out long ago
    assert prediction_age(100, 100, 3, 4, DT) == 0


# -- jitter and order --------------------------------------------------------------------------------

def _spec_extra(seed, receiver, sender, step, jitter) -> int:
    """Return the jitter draw in plain Python: floor(u (J + 1)) of the hashed uniform u, at most J."""
    return min(jitter, int(reference_hash(seed, receiver, sender, step, JITTER_STREAM) * (jitter + 1)))


def _spec_delivered(k, delay, jitter, loss, seed, receiver, sender) -> int:
    """Return the delivered step by its definition: the newest sent step among the states arrived by k."""
    arrived = [0] + [s for s in range(1, k + 1)
                     if reference_hash(seed, receiver, sender, s, LOSS_STREAM) >= loss
                     and s + delay + _spec_extra(seed, receiver, sender, s, jitter) <= k]
    return max(arrived)


def test_jitter_draws_cover_zero_to_jitter_steps_evenly():
    draws = np.array([arrival_extra(4, 3, 2, 1, s) for s in range(20000)])
    assert set(draws.tolist()) == {0, 1, 2, 3, 4}
    counts = np.bincount(draws, minlength=5)
    # 4000 expected per value; a binomial sd is 57, so 6 sd either way
    assert np.all(np.abs(counts - 4000) < 340), counts
    assert all(arrival_extra(4, 3, 2, 1, s) == _spec_extra(3, 2, 1, s, 4) for s in range(500))
    assert all(arrival_extra(0, 3, 2, 1, s) == 0 for s in range(100))


@pytest.mark.parametrize('delay, jitter, loss', [(0, 3, 0.0), (2, 5, 0.0), (4, 6, 0.3)])
def test_the_delivered_step_is_the_newest_arrived_state_and_never_goes_back(delay, jitter, loss):
    seed, receiver, sender = 5, 4, 1
    steps = [delivered_step(k, delay, jitter, loss, NO_DROPOUT, seed, receiver, sender) for k in range(300)]
    assert steps == [_spec_delivered(k, delay, jitter, loss, seed, receiver, sender) for k in range(300)]
    assert all(b >= a for a, b in zip(steps, steps[1:], strict=False))
    ages = np.array([k - s for k, s in enumerate(steps)])[50:]
    assert ages.min() >= delay and ages.max() > delay   # the jitter acts


def test_an_older_state_arriving_after_a_newer_one_is_ignored():
    delay, jitter, seed, receiver, sender = 2, 6, 1, 4, 1
    extra = [arrival_extra(jitter, seed, receiver, sender, s) for s in range(400)]
    # a state s overtaken by s + 1: it arrives at step k_s, after s + 1 has (at k_s or earlier)
    s = next(s for s in range(1, 399) if extra[s] > extra[s + 1] + 1)
    k_s = s + delay + extra[s]
    assert s + 1 + delay + extra[s + 1] < k_s
    received = ReceivedStates(receiver, (sender,), parse_scenario(paper_yaml(
        f'impairments: {{seed: {seed}, delay_steps: {delay}, jitter_steps: {jitter}}}'), source='j').impairments,
        DT)
    used = []
    for k in range(k_s + 1):
        received.receive(k, np.zeros(STATE_SIZE), {sender: np.full(STATE_SIZE, float(k))})
        used.append(received.sample_steps[sender])
        assert received.delivered[sender][0] == used[-1]   # the state of the step it names (no noise)
    assert used[k_s] > s and used[k_s - 1] >= s + 1   # s arrived last, and was not used
    assert s not in used[s + delay + extra[s + 1]:]


# -- the scenario keys -------------------------------------------------------------------------------

def test_the_scenario_reads_jitter_and_compensation_with_per_link_overrides():
    imp = parse_scenario(paper_yaml(_jittered('predict')), source='j').impairments
    assert imp.compensation == 'predict'
    assert imp.jitters[(4, 1)] == 9 and imp.jitters[(4, 2)] == 4 and imp.delays[(4, 1)] == 7
    assert set(imp.jitters) == set(imp.delays)
    plain = parse_scenario(paper_yaml('impairments: {delay_steps: 2}'), source='p').impairments
    assert plain.compensation == DEFAULT_COMPENSATION == 'predict' and not any(plain.jitters.values())
    only_jitter = parse_scenario(paper_yaml('impairments: {jitter_steps: 1}'), source='p').impairments
    assert only_jitter is not None   # jitter alone is an impairment


BAD = [
    ('impairments: {jitter_steps: -1}', 'impairments.jitter_steps', 'out of range; allowed: >= 0'),
    ('impairments:\n  links:\n    - {uh: 4, hears: 1, jitter_steps: -2}', r'impairments\.links\[0\]\.jitter_steps',
     'out of range; allowed: >= 0'),
    ('impairments: {jitter_steps: 1.5}', 'impairments.jitter_steps', 'expected a whole number of steps'),
    ('impairments: {delay_compensation: extrapolate}', 'impairments.delay_compensation',
     "'extrapolate' is not allowed; allowed: none, predict"),
    ('impairments:\n  links:\n    - {uh: 1, hears: 4, jitter_steps: 2}', r'impairments\.links\[0\]',
     'UH 1 does not hear UH 4: no such edge'),
]


@pytest.mark.parametrize('block, key, words', BAD)
def test_bad_jitter_and_compensation_are_refused_with_line_and_key(block, key, words):
    text = paper_yaml(block)
    with pytest.raises(E.ScenarioError) as info:
        parse_scenario(text, source='bad.yaml')
    message = str(info.value)
    line = len(text.splitlines())   # the block's last line holds the key
    assert re.search(rf'^bad\.yaml:{line}: {key}: ', message), message
    assert words in message, message


@pytest.mark.parametrize('block, key, words', BAD[:2] + BAD[3:4])
def test_a_run_with_a_bad_key_exits_2_with_one_line_and_starts_nothing(block, key, words, tmp_path, capsys):
    scenario = tmp_path / 'team.yaml'
    scenario.write_text(paper_yaml(block))
    out = tmp_path / 'out'
    with pytest.raises(SystemExit) as info:
        run_formation.main(['--scenario', str(scenario), '--out', str(out)])
    err = capsys.readouterr().err
    assert info.value.code == 2
    assert err.count('\n') == 1 and re.search(rf'team\.yaml:\d+: {key}: ', err) and words in err, err
    assert not out.exists() or not any(out.iterdir())


# -- the same numbers everywhere ---------------------------------------------------------------------

def test_zero_delay_runs_are_the_same_bit_for_bit_with_and_without_prediction():
    noisy = 'impairments:\n  seed: 3\n  noise: {position: 0.01, velocity: 0.01}\n'
    runs = [run_team_simulation(parse_scenario(paper_yaml(noisy + f'  delay_compensation: {c}\n'), source=c),
                                'proposed', duration=2.0) for c in ('none', 'predict')]
    for key in runs[0].ARRAY_KEYS:
        assert np.array_equal(getattr(runs[0], key), getattr(runs[1], key), equal_nan=True), key
    delayed = [run_team_simulation(parse_scenario(paper_yaml(noisy + f'  delay_steps: 2\n  delay_compensation: {c}\n'),
                                                  source=c), 'proposed', duration=2.0) for c in ('none', 'predict')]
    assert not np.array_equal(delayed[0].commands, delayed[1].commands)   # with a delay, prediction acts


def test_the_kernel_and_the_object_loop_agree_with_jitter_and_prediction():
    scenario = parse_scenario(paper_yaml(_jittered('predict')), source='jittered')
    kernel = run_team_simulation(scenario, 'case1', duration=2.0)
    objects = run_team_simulation(scenario, 'case1', duration=2.0, engine='objects')
    for key in kernel.ARRAY_KEYS:
        assert np.array_equal(getattr(kernel, key), getattr(objects, key)), key


@pytest.mark.dds
@pytest.mark.slow
def test_a_lockstep_distributed_run_with_jitter_and_prediction_equals_the_in_process_run(tmp_path):
    """Check a lockstep distributed run with delay, jitter, loss, noise, a dropout and prediction.

    Each controller node predicts with the functions the kernel calls, so the bag equals the
    in-process run to the bit; /uh4/received holds the states as delivered, each with its sent step.
    The prediction is ``reference_motion`` with ``reference_links: all_leaders`` (docs/delay.md#remedies):
    ``predict`` and the virtual leader's motion, which each node evaluates itself; ``predict`` alone is
    checked by tests/test_impairments.py's lockstep run.
    """
    from rosbags.rosbag2 import Reader
    from team_runs import assert_lockstep_run_equals_in_process

    from uh_runtime.messages import typestore

    text = re.sub(r'reference_links:\n(  - .*\n)+', 'reference_links: all_leaders\n',
                  paper_yaml(_jittered('reference_motion')))
    assert 'all_leaders' in text
    scenario = parse_scenario(text, source='jittered')
    out, reference = assert_lockstep_run_equals_in_process(tmp_path, scenario, text)
    store, imp, col = typestore(), scenario.impairments, {i: c for c, i in enumerate(scenario.ids)}
    expected, steps = np.empty(STATE_SIZE), []
    with Reader(out / 'bag') as reader:
        connections = [c for c in reader.connections if c.topic == '/uh4/received']
        for conn, _, raw in reader.messages(connections=connections):
            msg = store.deserialize_cdr(raw, conn.msgtype)
            state = msg.states[1]   # UH 1, over the link with delay 7 and jitter 9
            s = delivered_step(msg.step, 7, 9, 0.5, NO_DROPOUT, imp.seed, 4, 1)
            add_noise(reference.states[s, col[1]], imp.noise, imp.seed, 4, 1, s, expected)
            assert state.uh_id == 1 and state.step == s
            assert [state.position.x, state.position.y, state.position.z] == expected[:3].tolist()
            steps.append(s)
    assert len(steps) == 301 and all(b >= a for a, b in zip(steps, steps[1:], strict=False))


def test_a_campaign_spec_may_set_jitter_and_compensation(tmp_path):
    from uh_campaign.spec import load_spec

    spec = tmp_path / 'spec.yaml'
    spec.write_text(yaml.safe_dump({'name': 'j', 'scenario': 'paper', 'runs': 1,
                                    'impairments': {'jitter_steps': 2, 'delay_compensation': 'predict'}}))
    assert load_spec(spec).impairments == {'jitter_steps': 2, 'delay_compensation': 'predict'}


# --- why the leader ring oscillates from about ten steps of delay on (docs/delay.md#why-the-ring-oscillates) ---

def _loop_gains():
    """Give the paper gains of the ring model: outer k1, z2 gain, tau_1; inner k3, z4 gain, tau_2, tau_w (1/s, s)."""
    raw = yaml.safe_load((CONFIG / 'paper_gains.yaml').read_text())['/**']['ros__parameters']
    beta, outer, inner = raw['beta'], raw['outer'], raw['inner']
    return (outer['k'], beta / (2 * outer['r']), outer['tau_command'],
            inner['k'], beta / (2 * inner['r']), inner['tau_command'], inner['tau_rate'])


def _follow(s, d, x_of, v_of):
    """Transfer from a neighbour's position to a UH's position, one axis, small angles (docs/delay.md).

    The UH hears that one neighbour with weight 1 among degree ``d`` (the rest held still); it receives
    the neighbour's position as ``x_of * P_j`` and velocity as ``v_of * P_j``. Outer loop as in
    docs/control_law.md (the networks and observers left out), the inner loop's filters and gains,
    the command held over a step (dt / 2 of lag).
    """
    k1, kz2, tau1, k3, kz4, tau2, tauw = _loop_gains()
    fw = 1 / (1 + tauw * s)
    attitude = ((s + kz4) * fw * (k3 + s) + 1) / (s ** 2 + kz4 * s + 1 + (s + kz4) * fw * k3)
    attitude = attitude / (1 + tau2 * s) * np.exp(-s * DT / 2)   # acceleration achieved / u_p
    f1 = 1 / (1 + tau1 * s)
    lhs = s ** 2 / attitude + kz2 * s + (s + kz2) * f1 * k1 + d * d
    return ((s + kz2) * f1 * k1 / d + d) * x_of / lhs, (s + kz2) * f1 / d * v_of / lhs, attitude


def _first_unstable_delay(predict: bool, leaders_hear_reference: bool = False, most: int = 40):
    """First delay (steps on every ring link, <= most) at which the leader ring's loop encircles 1, or None."""
    w = np.linspace(0.005, 80.0, 20000)
    s = 1j * w
    for steps in range(most + 1):
        delay = np.exp(-s * steps * DT)
        x_of, v_of = delay * (1 + s * steps * DT) if predict else delay, delay * s
        h2 = sum(_follow(s, 2, x_of, v_of)[:2])         # UH 1 (and all three with the reference)
        loop = h2 ** 3 if leaders_hear_reference else h2 * sum(_follow(s, 1, x_of, v_of)[:2]) ** 2
        turn = np.unwrap(np.angle(1 - loop))
        if abs(turn[-1] - turn[0]) > np.pi:   # 1 - L(jw) winds around 0: a pair of unstable poles
            return steps
    return None


def test_the_leader_ring_has_a_loop_gain_above_one_near_7_rad_s_from_the_velocity_feed_forward():
    """docs/delay.md: a leader copies its neighbour with gain 1.34 at 7.5 rad/s, all of it through the velocity path."""
    w = np.array([0.1, 1.0, 7.5, 10.0])
    pos, vel, attitude = _follow(1j * w, 1, 1.0, 1j * w)
    follow = np.abs(pos + vel)
    assert abs(follow[0] - 1) < 1e-3 and 1.3 < follow[2] < 1.4          # copies slow motion, amplifies 7.5 rad/s
    assert abs(vel[2]) > 1.3 and abs(pos[2]) < 0.25                     # the velocity path carries it
    assert np.all(np.abs(np.abs(attitude) - 1) < 0.02)                  # the attitude loop is not the cause
    ring = np.abs(sum(_follow(1j * w, 2, 1.0, 1j * w)[:2]) * (pos + vel) ** 2)
    assert 1.2 < ring[2] < 1.3                                          # > 1: stable without delay by its phase only


def test_the_ring_model_puts_the_limit_where_the_sweep_measures_it():
    """Unstable from 9 steps without prediction, from 6 with p + v tau (measured: fine at 5, oscillating at 10)."""
    assert _first_unstable_delay(predict=False) == 9
    assert _first_unstable_delay(predict=True) == 6
    # a shorter chain: every leader hears the virtual leader, the ring's gain stays below 1
    assert _first_unstable_delay(predict=False, leaders_hear_reference=True) is None
