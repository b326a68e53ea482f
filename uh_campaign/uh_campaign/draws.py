"""The random draws of a campaign spec and its generated graphs: their records and their readers.

The keys, defaults and limits are in the module docstring of :mod:`uh_campaign.spec`
(``draws`` and ``generator``); :func:`read_draws` and :func:`read_generator` read those mappings
of a spec with the spec's :class:`~uh_topology.schema.ConfigContext`, :func:`read_range` any
``[low, high]`` range of it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from uh_core.layout import CHANNEL_NAMES
from uh_topology import errors as E
from uh_topology.scenario_keys import EVENT_KINDS
from uh_topology.schema import type_name, unit_suffix

__all__ = ['FaultDraws', 'LossDraws', 'Draws', 'GeneratorSpec', 'GENERATOR_WEIGHTS', 'read_range', 'read_generator',
           'read_draws', 'loss_step_range']

_DRAW_KEYS = ('position_spread', 'min_initial_separation', 'attitude_spread', 'yaw_spread', 'model_mismatch',
              'disturbance_amplitude', 'faults', 'losses')
_LOSS_REQUIRED = ('time',)
_LOSS_OPTIONAL = ('uhs', 'kind', 'channels')
#: The kinds of event a campaign draws (the scenario's ``events`` kinds).
LOSS_KINDS = EVENT_KINDS
_FAULT_KEYS = ('faulted_uhs', 'candidates', 'channels', 'channels_per_uh', 'rho', 'bias_constant',
               'bias_amplitude', 'bias_frequency', 'onset_time')
_GENERATOR_REQUIRED = ('leaders', 'followers')
_GENERATOR_OPTIONAL = ('reference_links', 'leader_edge_probability', 'follower_edge_probability', 'weights',
                       'attempts')
#: The link weights a generator can give (``generator.weights``).
GENERATOR_WEIGHTS = ('unit', 'normalised')


@dataclass(frozen=True)
class FaultDraws:
    """The fault draws of ``draws.faults`` (the module docstring of :mod:`uh_campaign.spec`).

    Ranges are ``(low, high)``; ``channels`` are channel indices, ``candidates`` UH ids (None:
    every UH).
    """

    faulted_uhs: tuple = (1, 1)
    candidates: tuple | None = None
    channels: tuple = (0, 1, 2, 3)
    channels_per_uh: tuple = (1, 1)
    rho: tuple = (0.7, 0.95)
    bias_constant: tuple = (0.0, 0.0)       # rad
    bias_amplitude: tuple = (0.0, 0.0)      # rad
    bias_frequency: tuple = (0.0, 0.0)      # rad/s
    onset_time: tuple = (10.0, 10.0)        # s


@dataclass(frozen=True)
class LossDraws:
    """The drawn loss of ``draws.losses`` (the module docstring of :mod:`uh_campaign.spec`).

    Every draw loses one UH of ``uhs`` (None: every UH) at a time drawn uniformly in ``time`` (s),
    rounded to a control step; ``kind`` ``stuck`` sticks one of its ``channels`` (indices) instead.
    """

    time: tuple                          # s, (low, high) within (0, duration)
    uhs: tuple | None = None
    kind: str = 'lost'
    channels: tuple = (0, 1, 2, 3)


@dataclass(frozen=True)
class Draws:
    """The random draws of a campaign (the module docstring of :mod:`uh_campaign.spec`).

    Spreads in m and rad, ranges ``(low, high)`` or None (not drawn).
    """

    position_spread: float = 0.0        # m
    min_initial_separation: float = 0.0  # m; 0: no condition on the drawn positions
    attitude_spread: float = 0.0        # rad, roll and pitch
    yaw_spread: float = 0.0             # rad
    model_mismatch: tuple | None = None
    disturbance_amplitude: tuple | None = None   # N
    faults: FaultDraws | None = None
    losses: LossDraws | None = None


@dataclass(frozen=True)
class GeneratorSpec:
    """Random graphs with N leaders and M followers (the module docstring of :mod:`uh_campaign.spec`)."""

    leaders: int
    followers: int
    reference_links: tuple = (1, 1)
    leader_edge_probability: float = 0.5
    follower_edge_probability: float = 0.5
    attempts: int = 100
    weights: str = 'unit'


def read_range(ctx, value, path, *, lo=None, hi=None, lo_open=False, hi_open=False, unit='', integer=False):
    """Read a ``[low, high]`` list with ``low <= high`` within the given bounds."""
    if not isinstance(value, list) or len(value) != 2:
        raise ctx.error(E.WrongTypeError, path, f'expected a range [low, high]{unit_suffix(unit)}, got '
                        f'{type_name(value)} {value!r}')
    if integer:
        low, high = (ctx.integer(v, path + (i,), lo=lo) for i, v in enumerate(value))
        if hi is not None and high > hi:
            raise ctx.error(E.InvalidValueError, path + (1,), f'value {high} out of range; allowed: <= {hi}')
    else:
        low, high = (ctx.number(v, path + (i,), lo=lo, hi=hi, lo_open=lo_open, hi_open=hi_open, unit=unit)
                     for i, v in enumerate(value))
    if low > high:
        raise ctx.error(E.InvalidValueError, path, f'inverted range [{value[0]}, {value[1]}]; allowed: '
                        f'[low, high] with low <= high')
    return low, high


def read_generator(ctx, raw) -> GeneratorSpec:
    """Read the ``generator`` mapping of a spec with ``ctx`` (its :class:`~uh_topology.schema.ConfigContext`).

    Raise the configuration errors of ``ctx`` for a bad key or value, and for probabilities under which
    no draw can satisfy Assumption 1 (a follower edge probability of 0; a leader edge probability of 0
    unless every leader is linked to the virtual leader).
    """
    path = ('generator',)
    ctx.mapping(raw, path, _GENERATOR_REQUIRED, _GENERATOR_OPTIONAL, what='a generator mapping')
    n = ctx.integer(raw['leaders'], path + ('leaders',), lo=1, what='an integer number of leaders >= 1')
    m = ctx.integer(raw['followers'], path + ('followers',), lo=1, what='an integer number of followers >= 1')
    links = read_range(ctx, raw.get('reference_links', [1, 1]), path + ('reference_links',), lo=1, hi=n,
                   integer=True)
    p_leader = ctx.number(raw.get('leader_edge_probability', 0.5), path + ('leader_edge_probability',),
                          lo=0.0, hi=1.0)
    p_follower = ctx.number(raw.get('follower_edge_probability', 0.5), path + ('follower_edge_probability',),
                            lo=0.0, hi=1.0)
    attempts = ctx.integer(raw.get('attempts', 100), path + ('attempts',), lo=1,
                           what='an integer number of attempts >= 1')
    weights = ctx.string(raw.get('weights', 'unit'), path + ('weights',), choices=GENERATOR_WEIGHTS)
    # Assumption 1 (docs/graph.md): every leader needs a path from the virtual leader, every
    # follower one from a leader; refuse the options under which no draw can give them
    if p_follower == 0.0:
        raise ctx.error(E.UnreachableFollowerError, path + ('follower_edge_probability',),
                        'with follower_edge_probability 0 no follower hears anyone, so none has a path from a '
                        'leader (Assumption 1); allowed: a probability in (0, 1]',
                        ids=tuple(range(n + 1, n + m + 1)))
    if p_leader == 0.0 and links[1] < n:
        raise ctx.error(E.UnreachableLeaderError, path + ('leader_edge_probability',),
                        f'with leader_edge_probability 0 only the {links[1]} leader(s) linked to the virtual '
                        f'leader are reached, never all {n} (Assumption 1); allowed: a probability > 0, or '
                        f'reference_links [{n}, {n}]')
    return GeneratorSpec(leaders=n, followers=m, reference_links=links, leader_edge_probability=p_leader,
                         follower_edge_probability=p_follower, attempts=attempts, weights=weights)


def read_draws(ctx, raw, n_uhs: int, *, duration: float, dt: float) -> Draws:
    """Read the ``draws`` mapping of a spec with ``ctx`` for a team of ``n_uhs`` UHs.

    Spreads in m and rad, the disturbance amplitude in N; an absent key draws nothing. ``duration``
    and ``dt`` (s) are the runs': a drawn loss happens within (0, duration) on a control step. Raise
    the configuration errors of ``ctx`` for a bad key or value.
    """
    path = ('draws',)
    ctx.mapping(raw, path, (), _DRAW_KEYS, what='a draws mapping')
    faults = _fault_draws(ctx, raw['faults'], n_uhs) if raw.get('faults') is not None else None
    losses = _loss_draws(ctx, raw['losses'], n_uhs, duration, dt) if raw.get('losses') is not None else None
    return Draws(
        position_spread=ctx.number(raw.get('position_spread', 0.0), path + ('position_spread',), lo=0.0, unit='m'),
        min_initial_separation=ctx.number(raw.get('min_initial_separation', 0.0), path + ('min_initial_separation',),
                                          lo=0.0, unit='m'),
        attitude_spread=ctx.number(raw.get('attitude_spread', 0.0), path + ('attitude_spread',), lo=0.0,
                                   hi=math.pi / 2, hi_open=True, unit='rad'),
        yaw_spread=ctx.number(raw.get('yaw_spread', 0.0), path + ('yaw_spread',), lo=0.0, unit='rad'),
        model_mismatch=(read_range(ctx, raw['model_mismatch'], path + ('model_mismatch',), lo=0.0, lo_open=True)
                        if raw.get('model_mismatch') is not None else None),
        disturbance_amplitude=(read_range(ctx, raw['disturbance_amplitude'], path + ('disturbance_amplitude',),
                                      lo=0.0, unit='N')
                               if raw.get('disturbance_amplitude') is not None else None),
        faults=faults, losses=losses)


def loss_step_range(time: tuple, duration: float, dt: float) -> tuple:
    """Give the control steps ``(first, last)`` a loss drawn in ``time`` (s) may fall on.

    The steps within the range (a bound within 1e-9 of a step counts as on it) and within the run,
    after step 0 and before the last; ``first > last`` when there is none.
    """
    steps = int(round(duration / dt))
    first = max(1, math.ceil(time[0] / dt - 1e-9))
    last = min(steps - 1, math.floor(time[1] / dt + 1e-9))
    return first, last


def _loss_draws(ctx, raw, n_uhs: int, duration: float, dt: float) -> LossDraws:
    """Read ``draws.losses``: ``time``, a range within (0, duration) holding a control step; ``uhs``, UH ids."""
    path = ('draws', 'losses')
    ctx.mapping(raw, path, _LOSS_REQUIRED, _LOSS_OPTIONAL, what='a losses mapping {uhs, time, kind, channels}')
    time = read_range(ctx, raw['time'], path + ('time',), lo=0.0, hi=duration, lo_open=True, hi_open=True, unit='s')
    first, last = loss_step_range(time, duration, dt)
    if first > last:
        raise ctx.error(E.InvalidValueError, path + ('time',), f'no control step (dt {dt:g} s) in [{time[0]:g}, '
                        f'{time[1]:g}] s within the run; allowed: a range holding a multiple of {dt:g} s in '
                        f'(0, {duration:g}) s')
    uhs = _uh_list(ctx, raw['uhs'], path + ('uhs',), n_uhs) if 'uhs' in raw else None
    kind = ctx.string(raw.get('kind', 'lost'), path + ('kind',), choices=LOSS_KINDS)
    if 'channels' in raw and kind != 'stuck':
        raise ctx.error(E.InvalidValueError, path + ('channels',), f'a {kind} draw has no channel; allowed: channels '
                        'only with kind: stuck')
    channels = _channels(ctx, raw['channels'], path + ('channels',)) if 'channels' in raw else (0, 1, 2, 3)
    return LossDraws(time=time, uhs=uhs, kind=kind, channels=channels)


def _uh_list(ctx, given, path: tuple, n_uhs: int) -> tuple:
    """Read a non-empty list of distinct UH ids of a team of ``n_uhs`` at key path ``path``."""
    if not isinstance(given, list) or not given:
        raise ctx.error(E.WrongTypeError, path,
                        f'expected a non-empty list of UH ids, got {type_name(given)} {given!r}')
    known = set(range(1, n_uhs + 1))
    for i, uh in enumerate(given):
        ctx.uh_id(uh, path + (i,), known)
        if uh in given[:i]:
            raise ctx.error(E.InvalidValueError, path + (i,), f'UH {uh} is listed twice')
    return tuple(given)


def _fault_draws(ctx, raw, n_uhs: int) -> FaultDraws:
    path = ('draws', 'faults')
    ctx.mapping(raw, path, (), _FAULT_KEYS, what='a fault draws mapping')
    candidates = _uh_list(ctx, raw['candidates'], path + ('candidates',), n_uhs) if 'candidates' in raw else None
    n_candidates = len(candidates) if candidates is not None else n_uhs
    channels = _channels(ctx, raw['channels'], path + ('channels',)) if 'channels' in raw else (0, 1, 2, 3)
    return FaultDraws(
        faulted_uhs=read_range(ctx, raw.get('faulted_uhs', [1, 1]), path + ('faulted_uhs',), lo=0, hi=n_candidates,
                           integer=True),
        candidates=candidates, channels=channels,
        channels_per_uh=read_range(ctx, raw.get('channels_per_uh', [1, 1]), path + ('channels_per_uh',), lo=1,
                               hi=len(channels), integer=True),
        rho=read_range(ctx, raw.get('rho', [0.7, 0.95]), path + ('rho',), lo=0.0, hi=1.0, lo_open=True),
        bias_constant=read_range(ctx, raw.get('bias_constant', [0.0, 0.0]), path + ('bias_constant',), unit='rad'),
        bias_amplitude=read_range(ctx, raw.get('bias_amplitude', [0.0, 0.0]), path + ('bias_amplitude',), lo=0.0,
                              unit='rad'),
        bias_frequency=read_range(ctx, raw.get('bias_frequency', [0.0, 0.0]), path + ('bias_frequency',), lo=0.0,
                              unit='rad/s'),
        onset_time=read_range(ctx, raw.get('onset_time', [10.0, 10.0]), path + ('onset_time',), lo=0.0, unit='s'))


def _channels(ctx, chans, path) -> tuple:
    """Read a non-empty list of channels without repeats (names or indices) as indices."""
    if not isinstance(chans, list) or not chans:
        raise ctx.error(E.WrongTypeError, path, f'expected a non-empty list of channels, got {type_name(chans)} '
                        f'{chans!r}')
    channels = tuple(_channel(ctx, c, path + (i,)) for i, c in enumerate(chans))
    for i, c in enumerate(channels):
        if c in channels[:i]:
            raise ctx.error(E.InvalidValueError, path + (i,), f'channel {CHANNEL_NAMES[c]} is listed twice')
    return channels


def _channel(ctx, value, path) -> int:
    """Read a channel of the fault draws: a name, or an integer index >= 0 (then 0..3)."""
    if not isinstance(value, str):
        value = ctx.integer(value, path, lo=0, what='a channel index 0..3 or name')
    return ctx.channel(value, path)
