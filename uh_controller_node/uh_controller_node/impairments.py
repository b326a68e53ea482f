"""What a controller receives under communication and sensing impairments (docs/campaigns.md#impairments).

The impairments of a scenario (:class:`uh_topology.scenario.ImpairmentSpec`) act in the receiving
controller, on control steps, and draw no random stream: every loss, every jitter and every noise
sample is a pure function of ``(seed, receiver, sender, step)`` (a SplitMix64 hash). So the
in-process kernel (:func:`uh_team.team_kernel.run_team_steps`), the object loop and the distributed
controller nodes (:class:`ReceivedStates`), whatever the order in which they meet the steps, compute
the same received states with the same compiled functions: the runs stay bit-identical.

The state neighbour j sends at step s reaches receiver i at step ``s + d_ij + e`` (:func:`arrival_extra`:
``e`` drawn in ``0..J_ij``, the link's jitter), unless the link loses it (probability ``l_ij``) or j
sent it at or after its dropout. At step k, i uses (:func:`newest_delivered`, :func:`delivered_step`)
the state with the *newest sent step* among those that have arrived: a state overtaken by a newer one
is never used, whatever the order of arrival. The state of step 0 is always delivered (every UH
starts knowing its neighbours' initial states). Noise is added to the delivered state
(:func:`add_noise`), keyed by the step it was sent at, so a state kept because later ones were lost
keeps its noise. The own state gets noise too (sensing), keyed by ``sender = receiver``; it is never
delayed nor lost. The reference is received unimpaired.

Delay compensation (docs/delay.md): with ``delay_compensation: predict`` the controller predicts the
position of a state sent ``k - s`` steps ago to step k from the velocity it carries
(:func:`predict_state`; over at most the link's delay and jitter plus :data:`PREDICTION_MARGIN`,
:func:`prediction_age`); a state of the current step is used as received, bit for bit.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from uh_core import compiled_kernels as _compiled_kernels
from uh_core import kernel_cache as _kernel_cache
from uh_core import layout as _layout
from uh_core.compiled_kernels import njit
from uh_core.layout import R_P, R_V, STATE_SIZE, X_P, X_V
from uh_topology.impairments import PREDICTING

__all__ = ['Link', 'LOSS_STREAM', 'JITTER_STREAM', 'PREDICTION_MARGIN', 'hash_uniform', 'arrival_extra',
           'newest_delivered', 'delivered_step', 'prediction_age', 'add_noise', 'predict_state', 'add_reference_motion',
           'ReceivedStates',
           'reference_hash', 'compile_impairment_kernels']

#: Stream of the loss draws; the noise of state component c uses streams 1 + 2c and 2 + 2c.
LOSS_STREAM = 0
#: Stream of the jitter draws (after the 2 x 12 noise streams).
JITTER_STREAM = 1 + 2 * STATE_SIZE
#: s a state is predicted beyond the link's delay and jitter at most (:func:`prediction_age`): the
#: realtime stale timeout (``uh_wire.run_config.DEFAULT_STALE_TIMEOUT``, equal by test), so a state
#: kept through losses is still predicted, that of a sender that dropped out is not extrapolated
#: without bound. A literal here: numba compiles it into the cached kernels, which it re-validates
#: against this file only.
PREDICTION_MARGIN = 0.25

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31, _S11 = np.uint64(30), np.uint64(27), np.uint64(31), np.uint64(11)
_UNIT = 1.0 / 9007199254740992.0   # 2^-53


@njit(cache=True)
def _splitmix(z):
    z = z + _GOLDEN
    z = (z ^ (z >> _S30)) * _MIX1
    z = (z ^ (z >> _S27)) * _MIX2
    return z ^ (z >> _S31)


@njit(cache=True)
def hash_uniform(seed, receiver, sender, step, stream):
    """Return a uniform number in [0, 1) from ``(seed, receiver, sender, step, stream)`` (all ints >= 0).

    SplitMix64 applied to each in turn, the top 53 bits scaled by 2^-53.
    """
    z = _splitmix(np.uint64(seed))
    z = _splitmix(z ^ np.uint64(receiver))
    z = _splitmix(z ^ np.uint64(sender))
    z = _splitmix(z ^ np.uint64(step))
    z = _splitmix(z ^ np.uint64(stream))
    return float(z >> _S11) * _UNIT


def reference_hash(seed: int, receiver: int, sender: int, step: int, stream: int) -> float:
    """:func:`hash_uniform` in plain Python integers (the specification the kernel is tested against)."""
    mask = (1 << 64) - 1

    def mix(z):
        z = (z + 0x9E3779B97F4A7C15) & mask
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & mask
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & mask
        return z ^ (z >> 31)

    z = mix(seed)
    for value in (receiver, sender, step, stream):
        z = mix(z ^ value)
    return (z >> 11) * 2.0 ** -53


@njit(cache=True)
def arrival_extra(jitter, seed, receiver, sender, step):
    """Extra steps, in ``0..jitter``, by which the link delays the state ``sender`` sent at ``step``.

    A uniform draw of :func:`hash_uniform` on :data:`JITTER_STREAM`; 0 without a hash when ``jitter`` is 0.
    """
    if jitter == 0:
        return 0
    extra = int(hash_uniform(seed, receiver, sender, step, JITTER_STREAM) * (jitter + 1))
    return extra if extra < jitter else jitter


@njit(cache=True)
def newest_delivered(k, newest, delay, jitter, loss, drop_step, seed, receiver, sender):
    """Newest step ``s <= newest`` whose state of ``sender`` has reached ``receiver`` by step ``k``.

    A state sent at step s arrives at step ``s + delay + arrival_extra(s)`` unless it is lost
    (probability ``loss``) or sent at or after ``drop_step``; step 0 always counts as delivered.
    ``delay``, ``jitter`` steps >= 0; ``receiver`` and ``sender`` are UH ids. Returns 0 when
    ``newest <= 0``.
    """
    s = k - delay
    if s > newest:
        s = newest
    if s >= drop_step:
        s = drop_step - 1
    while s > 0 and ((loss > 0.0 and hash_uniform(seed, receiver, sender, s, LOSS_STREAM) < loss)
                     or s + delay + arrival_extra(jitter, seed, receiver, sender, s) > k):
        s -= 1
    if s < 0:
        s = 0
    return s


@njit(cache=True)
def delivered_step(k, delay, jitter, loss, drop_step, seed, receiver, sender):
    """Step of the state of ``sender`` that ``receiver`` uses at step ``k`` (see the module docstring).

    ``delay`` and ``jitter`` steps >= 0, ``loss`` probability in [0, 1), ``drop_step`` the sender's
    first step nobody receives; ``receiver`` and ``sender`` are UH ids. It never decreases with ``k``:
    the set of arrived states only grows, and the newest of them is used.
    """
    return newest_delivered(k, k, delay, jitter, loss, drop_step, seed, receiver, sender)


@njit(cache=True)
def add_noise(state, sigma, seed, receiver, sender, step, out):
    """Write ``out = state + sigma * g``, ``g`` standard normal per component.

    ``g`` comes from Box-Muller on two hashed uniforms, keyed by the step the state was sent at;
    components with ``sigma == 0`` are copied.
    """
    for c in range(STATE_SIZE):
        if sigma[c] == 0.0:
            out[c] = state[c]
        else:
            u1 = hash_uniform(seed, receiver, sender, step, 1 + 2 * c)
            u2 = hash_uniform(seed, receiver, sender, step, 2 + 2 * c)
            g = math.sqrt(-2.0 * math.log(1.0 - u1)) * math.cos(2.0 * math.pi * u2)
            out[c] = state[c] + sigma[c] * g


@njit(cache=True)
def prediction_age(k, s, delay, jitter, dt):
    """Return the steps over which the state sent at step ``s`` is predicted at step ``k`` (``dt`` s).

    ``k - s``, but at most ``delay + jitter`` plus :data:`PREDICTION_MARGIN` in steps.
    """
    horizon = delay + jitter + int(PREDICTION_MARGIN / dt + 0.5)
    age = k - s
    return age if age < horizon else horizon


@njit(cache=True)
def predict_state(state, age, dt, out):
    """Write ``out`` = ``state``, sent ``age`` steps ago, predicted to the current step (docs/delay.md).

    Parameters
    ----------
    state : ndarray (12,)
        The state as received, ``[p m, v m/s, Theta rad, omega rad/s]`` (inertial p and v).
    age : int
        Steps >= 0 since it was sent (:func:`prediction_age`).
    dt : float
        Control period, s.

    The position becomes ``p + v tau`` with ``tau = age dt`` s (the first-order lag removed); the
    velocity, attitude and body rates are copied (docs/delay.md says why the velocity is not
    extrapolated). At ``age == 0`` every component is copied unchanged, bit for bit.
    """
    for c in range(STATE_SIZE):
        out[c] = state[c]
    if age == 0:
        return
    tau = age * dt
    for c in range(3):
        out[X_P + c] = state[X_P + c] + state[X_V + c] * tau


@njit(cache=True)
def add_reference_motion(ref_sent, ref_now, tau, out):
    """Add the virtual leader's own motion over ``tau`` s to a predicted state ``out`` (docs/delay.md#remedies).

    ``delay_compensation: reference_motion``. ``ref_sent``, ``ref_now`` (7,) are ``[p_0, v_0, psi_0]``
    at the step the state was sent and at that step plus the age predicted over. The position gains
    what the prediction ``p + v tau`` misses of the reference, ``p_0(now) - p_0(sent) - v_0(sent) tau``;
    the velocity gains ``v_0(now) - v_0(sent)``. The terms come from the known trajectory, not from
    any neighbour, so they close no loop: the team's delay margin is that of ``predict``.
    """
    for c in range(3):
        out[X_P + c] += ref_now[R_P + c] - ref_sent[R_P + c] - ref_sent[R_V + c] * tau
        out[X_V + c] += ref_now[R_V + c] - ref_sent[R_V + c]


class Link(NamedTuple):
    """The impairment of the link that brings ``sender``'s states to ``receiver``.

    Its fields are in the order :func:`newest_delivered` and :func:`delivered_step` take them after
    their first arguments, so ``newest_delivered(k, newest, *link)`` works. A new per-link
    impairment is one more field here and one more argument of those kernels.
    """

    delay: int          # steps
    jitter: int         # steps, the largest extra delay (0..jitter)
    loss: float         # probability that a state is lost
    drop_step: int      # the first step the sender no longer reaches the receiver (dropout)
    seed: int           # the scenario's impairment seed
    receiver: int       # UH id
    sender: int         # UH id


class ReceivedStates:
    """The states one controller receives, step by step (a distributed node or the object loop).

    Parameters
    ----------
    uh_id : int
        The receiving UH.
    neighbours : sequence of int
        The UHs it hears, ascending.
    impairments : ImpairmentSpec
    dt : float
        Control period, s (for the dropout times and the prediction).
    reference : VirtualLeaderReference or None
        The virtual leader's trajectory (``uh_core.reference``); needed with ``delay_compensation:
        reference_motion`` (:func:`add_reference_motion`), not read otherwise.

    :meth:`receive` is called once per step, in step order, with the states *sent* at that step
    (lockstep); it keeps only the states a later step may still deliver.
    """

    def __init__(self, uh_id: int, neighbours, impairments, dt: float, reference=None):
        self.uh_id = int(uh_id)
        self.neighbours = tuple(int(j) for j in neighbours)
        self.seed = int(impairments.seed)
        self.dt = float(dt)
        self.delay = {j: int(impairments.delays[(self.uh_id, j)]) for j in self.neighbours}
        self.jitter = {j: int(impairments.jitters[(self.uh_id, j)]) for j in self.neighbours}
        self.loss = {j: float(impairments.losses[(self.uh_id, j)]) for j in self.neighbours}
        self.drop = {j: impairments.drop_step(j, dt) for j in self.neighbours}
        self.sigma = np.ascontiguousarray(impairments.noise, dtype=float)
        self.predict = impairments.compensation in PREDICTING
        self.reference = reference if impairments.compensation == 'reference_motion' else None
        if impairments.compensation == 'reference_motion' and reference is None:
            raise ValueError('delay_compensation reference_motion needs the virtual leader\'s trajectory')
        self.history = {j: {} for j in self.neighbours}
        self.sample_steps = {}
        self.delivered = {}

    def receive(self, k: int, own, neighbours: dict):
        """Return the own state and the neighbour states the controller uses at step ``k``.

        From those sent at step ``k``: ``(own, {j: state})`` (new arrays), each neighbour's state
        predicted to step ``k`` when the scenario asks for it; :attr:`sample_steps` then holds the
        step each neighbour's state was sent at and :attr:`delivered` the states as delivered
        (noise included, not predicted).
        """
        own_out = np.empty(STATE_SIZE)
        add_noise(np.ascontiguousarray(own, dtype=float), self.sigma, self.seed, self.uh_id, self.uh_id, k, own_out)
        out, self.delivered = {}, {}
        for j in self.neighbours:
            history = self.history[j]
            if k < self.drop[j] or k == 0:   # later states of a UH that dropped out are never delivered;
                # the initial state always is (a dropout at t = 0 leaves its neighbours with it)
                history[k] = np.array(neighbours[j], dtype=float)   # a copy: the sender may reuse its array
            link = self.link(j)
            out[j] = self.use(j, k, delivered_step(k, *link), link)
        return own_out, out

    def link(self, j: int) -> Link:
        """Return the :class:`Link` from neighbour ``j`` to this UH."""
        return Link(self.delay[j], self.jitter[j], self.loss[j], self.drop[j], self.seed, self.uh_id, j)

    def use(self, j: int, k: int, s: int, link: Link):
        """Return the state neighbour ``j`` sent at step ``s`` as used at step ``k`` (a new array).

        Noise added (:attr:`delivered` keeps it so), predicted to step ``k`` when the scenario asks for it;
        :attr:`sample_steps` records ``s``, and the held states older than ``s`` are dropped (the step
        used never goes back).
        """
        history = self.history[j]
        state = self.delivered[j] = np.empty(STATE_SIZE)
        add_noise(history[s], self.sigma, self.seed, self.uh_id, j, s, state)
        used = state
        if self.predict and s < k:
            used = np.empty(STATE_SIZE)
            age = prediction_age(k, s, link.delay, link.jitter, self.dt)
            predict_state(state, age, self.dt, used)
            if self.reference is not None:
                add_reference_motion(self.reference.row(s * self.dt), self.reference.row((s + age) * self.dt),
                                     age * self.dt, used)
        self.sample_steps[j] = s
        for old in [step for step in history if step < s]:
            del history[old]
        return used


def compile_impairment_kernels() -> float:
    """Compile (or load from numba's cache) the kernels of this module; returns the seconds spent."""
    import time

    start = time.perf_counter()
    delivered_step(5, 1, 2, 0.5, 3, 1, 2, 3)
    newest_delivered(5, 4, 1, 2, 0.5, 3, 1, 2, 3)   # also called from Python (realtime_received)
    add_noise(np.zeros(STATE_SIZE), np.ones(STATE_SIZE), 1, 2, 3, 4, np.empty(STATE_SIZE))
    predict_state(np.zeros(STATE_SIZE), prediction_age(5, 3, 1, 2, 0.01), 0.01, np.empty(STATE_SIZE))
    add_reference_motion(np.zeros(7), np.zeros(7), 0.01, np.zeros(STATE_SIZE))
    return time.perf_counter() - start


# numba caches each kernel by this file only: empty the cache when the layout it reads changes
_kernel_cache.refresh_cache(_kernel_cache.module_dispatchers(globals()), [_layout.__file__])

# run the ahead-of-time compiled kernels instead where this process asks for them (docs/performance.md#memory)
_compiled_kernels.install(globals())
