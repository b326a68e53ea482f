"""The ``impairments`` of a scenario: what each controller receives (docs/campaigns.md#impairments).

:class:`ImpairmentSpec` is the validated form; :func:`read_impairments` reads it from the
scenario's mapping with the keys of :data:`uh_topology.scenario_keys.IMPAIRMENT_KEYS` (which keys
there are, their defaults and ranges) and checks the links against the graph. What a receiving
controller does with them is ``uh_controller_node/impairments.py``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from types import MappingProxyType
from typing import Mapping

import numpy as np

from . import errors as E
from . import scenario_keys
from .scenario_keys import IMPAIRMENT_KEYS, key_named, key_names, read_key
from .schema import ConfigContext, read_only_array, type_name

__all__ = ['ImpairmentSpec', 'NO_DROPOUT', 'COMPENSATIONS', 'PREDICTING', 'DEFAULT_COMPENSATION', 'read_impairments',
           'uniform_impairments']

#: The values of ``impairments.delay_compensation``: states used as received, predicted to the current
#: step, or predicted with the virtual leader's own motion added (docs/delay.md#remedies).
COMPENSATIONS = key_named(IMPAIRMENT_KEYS, 'delay_compensation').choices
#: The compensations that predict each received state to the current step (``p + v tau``).
PREDICTING = ('predict', 'reference_motion')
#: ``impairments.delay_compensation`` when the key is absent (docs/delay.md says why).
DEFAULT_COMPENSATION = key_named(IMPAIRMENT_KEYS, 'delay_compensation').default

#: :meth:`ImpairmentSpec.drop_step` of a UH that never drops out.
NO_DROPOUT = 2 ** 62


@dataclass(frozen=True, eq=False)
class ImpairmentSpec:
    """Deterministic communication and sensing impairments: what each controller receives.

    See docs/campaigns.md#impairments. They act in the receiving controller, on control steps, so
    they are defined for the in-process run and the lockstep distributed run (identically), and in
    real time on the states' sent steps (docs/runtime.md#impairments-in-real-time).

    Attributes
    ----------
    seed : int
        Seeds the loss and jitter draws and the noise (with receiver, sender and step: no random stream).
    delays : mapping {(i, j): int}
        Steps by which the link "UH i hears UH j" delays every state, for every edge (>= 0).
    jitters : mapping {(i, j): int}
        Largest extra delay of the link, steps (>= 0): each state is delayed by a further draw in
        ``0..jitter``, so states may arrive out of order (the newest sent one is used).
    losses : mapping {(i, j): float}
        Probability in [0, 1) that the link loses a state (the receiver keeps the newest one it got).
    noise : ndarray (12,)
        Standard deviation of the zero-mean Gaussian noise added to every state a controller receives
        (its own and its neighbours'), per state component: m, m/s, rad, rad/s.
    dropouts : mapping {uh id: float}
        Time from which no other UH receives the UH's state, s.
    compensation : str
        ``'none'`` or ``'predict'``: whether a controller predicts each neighbour's state from the
        step it was sent at to the current step (docs/delay.md).
    """

    seed: int
    delays: Mapping
    losses: Mapping
    noise: np.ndarray
    dropouts: Mapping
    jitters: Mapping
    compensation: str

    @property
    def is_active(self) -> bool:
        """Whether anything is impaired (all zero: the run is that without impairments)."""
        return (any(self.delays.values()) or any(self.jitters.values()) or any(self.losses.values())
                or bool(np.any(self.noise)) or bool(self.dropouts))

    def drop_step(self, uh: int, dt: float) -> int:
        """First step whose state of ``uh`` no other UH receives (a huge number without a dropout)."""
        t = self.dropouts.get(int(uh))
        return NO_DROPOUT if t is None else int(math.ceil(t / dt - 1e-9))


def read_impairments(ctx: ConfigContext, raw, adjacency: np.ndarray, known: set, duration: float) -> ImpairmentSpec:
    """Validate the ``impairments`` mapping ``raw`` against the graph ``adjacency`` (``a_ij``, column 0 the leader).

    ``known`` are the UH ids, ``duration`` the run's length (s, the latest dropout). The checks run
    in this order: the keys, the scalar keys other than the per-link ones (in the order of the
    table), the per-link keys, ``links``, ``noise``, ``dropouts``.
    """
    path = ('impairments',)
    table = scenario_keys.IMPAIRMENT_KEYS
    ctx.mapping(raw, path, (), key_names(table), what='an impairments mapping')
    scalars = {key.name: read_key(ctx, key, raw, path) for key in table if key.kind is not None and not key.per_link}
    link_keys = [key for key in table if key.per_link]
    edges = [(int(i), int(j) + 1) for i, j in zip(*np.nonzero(adjacency[:, 1:] > 0.0), strict=True)]   # (uh, hears)
    per_link = {key.name: dict.fromkeys(edges, read_key(ctx, key, raw, path)) for key in link_keys}
    _read_links(ctx, raw.get('links') or [], link_keys, per_link, set(edges), known)
    noise_raw = raw.get('noise') or {}
    noise_keys = scenario_keys.NOISE_KEYS
    ctx.mapping(noise_raw, path + ('noise',), (), key_names(noise_keys), what='a noise mapping')
    noise = np.concatenate([np.full(3, read_key(ctx, key, noise_raw, path + ('noise',))) for key in noise_keys])
    dropouts = _read_dropouts(ctx, raw.get('dropouts') or [], known, duration)
    return ImpairmentSpec(seed=scalars['seed'], delays=MappingProxyType(per_link['delay_steps']),
                          losses=MappingProxyType(per_link['loss']), noise=read_only_array(noise),
                          dropouts=MappingProxyType(dropouts), jitters=MappingProxyType(per_link['jitter_steps']),
                          compensation=scalars['delay_compensation'])


def uniform_impairments(adjacency: np.ndarray, delay_steps: int, compensation: str) -> ImpairmentSpec:
    """Give the impairments of ``delay_steps`` on every link of ``adjacency`` and nothing else (the delay margin's).

    ``compensation`` is ``'none'`` or ``'predict'``; seed 0, no jitter, loss, noise or dropout.
    """
    edges = [(int(i), int(j) + 1) for i, j in zip(*np.nonzero(adjacency[:, 1:] > 0.0), strict=True)]
    return ImpairmentSpec(seed=0, delays=MappingProxyType(dict.fromkeys(edges, int(delay_steps))),
                          losses=MappingProxyType(dict.fromkeys(edges, 0.0)), noise=read_only_array(np.zeros(12)),
                          dropouts=MappingProxyType({}), jitters=MappingProxyType(dict.fromkeys(edges, 0)),
                          compensation=compensation)


def _read_links(ctx: ConfigContext, links, link_keys: list, per_link: dict, edges: set, known: set) -> None:
    """Write the per-link overrides of ``impairments.links`` into ``per_link`` ({key: {(uh, hears): value}})."""
    path = ('impairments', 'links')
    if not isinstance(links, list):
        raise ctx.error(E.WrongTypeError, path, f'expected a list of links, got {type_name(links)}')
    names = key_names(link_keys)
    for idx, link in enumerate(links):
        lp = path + (idx,)
        ctx.mapping(link, lp, ('uh', 'hears'), names, what='a link mapping {uh, hears, ' + ', '.join(names) + '}')
        i = ctx.uh_id(link['uh'], lp + ('uh',), known)
        j = ctx.uh_id(link['hears'], lp + ('hears',), known)
        if (i, j) not in edges:
            raise ctx.error(E.InvalidValueError, lp, f'UH {i} does not hear UH {j}: no such edge in `edges`; '
                            f'impairments act on existing links only')
        for key in link_keys:
            if key.name in link:
                per_link[key.name][(i, j)] = read_key(ctx, key, link, lp)


def _read_dropouts(ctx: ConfigContext, drops, known: set, duration: float) -> dict:
    """Read ``impairments.dropouts`` as ``{uh id: time (s)}``: one per UH, in [0, duration]."""
    path = ('impairments', 'dropouts')
    if not isinstance(drops, list):
        raise ctx.error(E.WrongTypeError, path, f'expected a list of dropouts, got {type_name(drops)}')
    dropouts = {}
    for idx, drop in enumerate(drops):
        dp = path + (idx,)
        ctx.mapping(drop, dp, ('uh', 'time'), (), what='a dropout mapping {uh, time}')
        i = ctx.uh_id(drop['uh'], dp + ('uh',), known)
        if i in dropouts:
            raise ctx.error(E.InvalidValueError, dp + ('uh',), f'UH {i} already drops out; one dropout per UH')
        dropouts[i] = ctx.number(drop['time'], dp + ('time',), lo=0.0, hi=duration, unit='s')
    return dropouts
