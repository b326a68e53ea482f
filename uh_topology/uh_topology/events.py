"""Read a scenario's ``events`` and ``resilience`` (docs/scenario.md#events, docs/resilience.md).

``events`` says what happens to the team during a run (a helicopter ``lost`` at a time, an actuator
``stuck``); ``resilience`` how the team answers: re-form (:mod:`uh_topology.reform`) or hold, through
which standby edges, after which timeout a silent neighbour is declared lost, and whether a UH whose
fault isolator finds a fault it cannot compensate leaves the team. The keys, their defaults and
ranges are :data:`~uh_topology.scenario_keys.EVENT_KEYS` and
:data:`~uh_topology.scenario_keys.RESILIENCE_KEYS`.
"""
from __future__ import annotations

from dataclasses import dataclass

from . import errors as E
from .scenario_keys import EVENT_KEYS, RESILIENCE_KEYS, key_named, key_names, read_key
from .schema import ConfigContext, type_name

__all__ = ['TeamEvent', 'silent_events', 'ResilienceSpec', 'read_events', 'read_resilience', 'STANDBY_RULES']

#: The rules ``standby_edges`` may name instead of a list.
STANDBY_RULES = ('bypass', 'none')


@dataclass(frozen=True)
class TeamEvent:
    """What happens to UH ``uh`` at ``time`` (s), from step ``step = round(time / dt)`` on.

    ``kind`` ``lost``: it publishes nothing (its failsafe brakes it to a hover); ``stuck``: the
    actuator of ``channel`` (0..3, None for ``lost``) stays where it is at that step
    (:func:`uh_sim_node.plant_kernels.stuck_position`).
    """

    time: float
    uh: int
    kind: str
    step: int
    channel: int | None = None


def silent_events(events) -> tuple:
    """Give the events of kind ``lost`` (the UHs that stop publishing) of ``events``."""
    return tuple(e for e in events if e.kind == 'lost')


@dataclass(frozen=True)
class ResilienceSpec:
    """How the team answers a loss (docs/resilience.md).

    Attributes
    ----------
    on_loss : str
        ``reform`` or ``hold``.
    standby : str or tuple of (int, int)
        ``'bypass'``, ``'none'`` or the listed standby edges ``(uh, hears)`` (``hears = 0``: the
        virtual leader).
    lost_timeout : float
        s: a neighbour whose newest state is this old is declared lost.
    on_unable : str
        ``leave`` or ``stay``: what a UH does when its isolator finds a channel below ``unable_rho``.
    unable_rho : float
        The effectiveness floor (-) of that finding (docs/resilience.md#leaving-the-team).
    unable_spread : float
        rad: the command's standard deviation over the isolator's fit must exceed it for that finding.
    leave_climb : float
        m: how far a leaving UH climbs above the point where it declared itself.
    """

    on_loss: str = key_named(RESILIENCE_KEYS, 'on_loss').default
    standby: str | tuple = key_named(RESILIENCE_KEYS, 'standby_edges').default
    lost_timeout: float = key_named(RESILIENCE_KEYS, 'lost_timeout').default
    on_unable: str = key_named(RESILIENCE_KEYS, 'on_unable').default
    unable_rho: float = key_named(RESILIENCE_KEYS, 'unable_rho').default
    unable_spread: float = key_named(RESILIENCE_KEYS, 'unable_spread').default
    leave_climb: float = key_named(RESILIENCE_KEYS, 'leave_climb').default

    @property
    def leaves(self) -> bool:
        """A UH that finds a fault it cannot compensate leaves the team (``on_unable: leave``)."""
        return self.on_unable == 'leave'

    def lost_steps(self, dt: float) -> int:
        """Give the timeout in whole control steps (rounded up)."""
        return int(-(-round(self.lost_timeout / dt, 9) // 1))


def read_events(ctx: ConfigContext, raw, known: set, dt: float, duration: float) -> tuple:
    """Read ``events`` as a tuple of :class:`TeamEvent` sorted by time, then UH."""
    path = ('events',)
    if raw is None:
        return ()
    if not isinstance(raw, list):
        raise ctx.error(E.WrongTypeError, path, f'expected a list of events {{time, uh, kind}}, got {type_name(raw)}')
    events, lost = [], set()
    for idx, entry in enumerate(raw):
        ep = path + (idx,)
        ctx.mapping(entry, ep, key_names(EVENT_KEYS, required=True), key_names(EVENT_KEYS, required=False),
                    what='an event mapping {time, uh, kind}')
        uh = ctx.uh_id(entry['uh'], ep + ('uh',), known)
        time = read_key(ctx, key_named(EVENT_KEYS, 'time'), entry, ep, lo=0.0, hi=duration, lo_open=True,
                        hi_open=True)
        if round(time / dt) < 1:
            raise ctx.error(E.InvalidValueError, ep + ('time',), f'value {time!r} s falls on step 0 (dt {dt:g} s); '
                            f'allowed: a time on step 1 or later, >= {0.5 * dt:g} s')
        kind = read_key(ctx, key_named(EVENT_KEYS, 'kind'), entry, ep)
        channel = None
        if kind == 'stuck':
            if 'channel' not in entry:
                raise ctx.error(E.MissingFieldError, ep, 'a stuck event needs channel; allowed: collective, '
                                'tail_rotor, lateral, longitudinal (or 0..3)')
            channel = ctx.channel(entry['channel'], ep + ('channel',))
        elif 'channel' in entry:
            raise ctx.error(E.InvalidValueError, ep + ('channel',), f'a {kind} event has no channel; allowed: '
                            'channel only with kind: stuck')
        if uh in lost:
            raise ctx.error(E.InvalidValueError, ep + ('uh',), f'UH {uh} already has an event; one event per UH')
        lost.add(uh)
        events.append(TeamEvent(time=time, uh=uh, kind=kind, step=int(round(time / dt)), channel=channel))
    return tuple(sorted(events, key=lambda e: (e.time, e.uh)))


#: A live link may be declared lost only with a probability below this per state (a run of ``lost_steps`` lost).
FALSE_LOSS_PROBABILITY = 1e-12


def read_resilience(ctx: ConfigContext, raw, adjacency, known: set, link_age: float, *, dt: float = 1.0,
                    worst_loss: float = 0.0, dropouts: bool = False) -> ResilienceSpec | None:
    """Read ``resilience`` (None when absent).

    ``link_age``: the largest age a live link gives, s; ``worst_loss`` the largest loss probability of a
    link; ``dropouts``: the scenario has ``impairments.dropouts`` (refused: its receivers would declare the
    dropped UH lost, which an in-process run does not model; an event of kind ``lost`` is that loss).
    """
    if raw is None:
        return None
    path = ('resilience',)
    ctx.mapping(raw, path, (), key_names(RESILIENCE_KEYS), what='a resilience mapping')
    on_loss = read_key(ctx, key_named(RESILIENCE_KEYS, 'on_loss'), raw, path)
    timeout = read_key(ctx, key_named(RESILIENCE_KEYS, 'lost_timeout'), raw, path)
    if timeout <= link_age:
        raise ctx.error(E.InvalidValueError, path + ('lost_timeout',), f'value {timeout!r} s is not beyond the '
                        f'largest age the links give ({link_age:g} s: delay and jitter); allowed: > {link_age:g} s')
    spec = ResilienceSpec(on_loss=on_loss, standby=None, lost_timeout=timeout)
    run = spec.lost_steps(dt) - int(round(link_age / dt))    # states lost in a row that declare a live link lost
    if worst_loss > 0.0 and worst_loss ** max(run, 1) > FALSE_LOSS_PROBABILITY:
        raise ctx.error(E.InvalidValueError, path + ('lost_timeout',), f'value {timeout!r} s: a live link losing '
                        f'{worst_loss:g} of its states is declared lost with probability {worst_loss:g}^{run} > '
                        f'{FALSE_LOSS_PROBABILITY:g} per state; allowed: a longer timeout or less loss')
    if dropouts:
        raise ctx.error(E.InvalidValueError, path, 'a scenario with resilience or events cannot have '
                        'impairments.dropouts (its receivers would declare the dropped UH lost); allowed: an event '
                        '{time, uh, kind: lost} instead')
    standby = _standby(ctx, raw.get('standby_edges', key_named(RESILIENCE_KEYS, 'standby_edges').default),
                       path + ('standby_edges',), adjacency, known)
    unable = {name: read_key(ctx, key_named(RESILIENCE_KEYS, name), raw, path)
              for name in ('on_unable', 'unable_rho', 'unable_spread', 'leave_climb')}
    return ResilienceSpec(on_loss=on_loss, standby=standby, lost_timeout=timeout, **unable)


def _standby(ctx: ConfigContext, raw, path, adjacency, known: set):
    """Read ``standby_edges``: a rule of :data:`STANDBY_RULES` or a list ``{uh, hears}``."""
    if isinstance(raw, str):
        return ctx.string(raw, path, choices=STANDBY_RULES)
    if not isinstance(raw, list):
        raise ctx.error(E.WrongTypeError, path, f'expected {" or ".join(STANDBY_RULES)} or a list of {{uh, hears}}, '
                        f'got {type_name(raw)}')
    edges = []
    for idx, entry in enumerate(raw):
        ep = path + (idx,)
        ctx.mapping(entry, ep, ('uh', 'hears'), (), what='a standby edge {uh, hears}')
        i = ctx.uh_id(entry['uh'], ep + ('uh',), known)
        j = entry['hears']
        if not (type(j) is int and j == 0):
            j = ctx.uh_id(j, ep + ('hears',), known, what='UH id (or 0, the virtual leader)')
        if i == j:
            raise ctx.error(E.InvalidValueError, ep + ('hears',), f'UH {i} cannot hear itself')
        if adjacency[i, j] > 0.0:
            raise ctx.error(E.InvalidValueError, ep, f'UH {i} already hears {j} (a declared edge); a standby edge '
                            'is one the graph does not declare')
        if (i, j) in edges:
            raise ctx.error(E.InvalidValueError, ep, f'standby edge {i} hears {j} is listed twice')
        edges.append((i, j))
    return tuple(sorted(edges))
