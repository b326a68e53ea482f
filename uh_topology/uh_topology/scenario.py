"""Scenario loading and validation: team, communication graph, faults, reference (docs/graph.md, docs/scenario.md).

A scenario is one YAML file (see ``uh_topology/config/paper.yaml`` for a commented example)::

    name: paper                 # str
    description: ...            # optional str
    dt: 0.01                    # control period, s (> 0)
    substeps: 5                 # RK4 substeps per control period (int >= 1), default 5
    duration: 60.0              # s, a multiple of dt
    settle_time: 20.0           # s, metrics are taken after it; default 20
    model_mismatch: 0.9         # controller's nominal D_v, c_Q = factor x true; default 0.9
    helicopter: helicopter      # helicopter parameter file: bundled name or path (relative to this file)
    gains: paper_gains.yaml     # gains: file (relative to this file) or an inline mapping
    uhs:                        # ids 1..N+M, leaders first
      - {id: 1, role: leader, offset: [3, 0, 0], initial_state: {position: [2, -1, 8]}}
      - {id: 4, role: follower, initial_state: {position: [1, 1, 6], velocity: [0, 0, 0],
                                                euler: [0, 0, 0], omega: [0, 0, 0]}}
    edges:                      # UH `uh` hears UH `hears` with weight a_ij (default 1)
      - {uh: 2, hears: 1, weight: 1.0}
    reference_links:           # leaders hearing the virtual leader (id 0), weight a_i0 (default 1)
      - {uh: 1, weight: 1.0}
    reference: {radius: 10, angular_rate: 0.1, center: [0, 10, 10], climb_rate: 0.1,
                yaw_rate: 0.1, initial_yaw: 0}
    disturbance: {amplitude: [..], frequency: [..], phase: [..], phase_per_id: 0.0}   # optional
    faults:                     # optional; channel: 0..3 or collective|tail_rotor|lateral|longitudinal
      - {uh: 2, channel: collective, rho: 0.8, bias_constant: 0, bias_amplitude: 0.01,
         bias_frequency: 0.5, onset_time: 10}
    impairments:                # optional; what the controllers receive (docs/campaigns.md#impairments)
      seed: 0                   # int >= 0: the loss and jitter draws and the noise
      delay_steps: 0            # int >= 0: a link delivers the state sent delay_steps steps earlier
      jitter_steps: 0           # int >= 0: each state is delayed by a further draw in 0..jitter_steps steps
      loss: 0.0                 # [0, 1): probability that a link loses a state
      links: [{uh: 4, hears: 1, delay_steps: 5, jitter_steps: 2, loss: 0.2}]    # per-link overrides (an edge)
      delay_compensation: predict   # none | predict: states predicted to the current step (docs/delay.md)
      noise: {position: 0.01, velocity: 0.0, attitude: 0.0, rate: 0.0}   # std devs m, m/s, rad, rad/s
      dropouts: [{uh: 3, time: 30.0}]   # from this time on no other UH receives uh 3's state

Validation raises the specific :mod:`uh_topology.errors` types with the file, line and key path.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np

from uh_core.layout import CHANNEL_ALIASES
from uh_core.records import FaultSpec

from . import errors as E
from .schema import CONFIG_DIR, ConfigContext, parse_yaml, read_config_file, read_only_array, type_name
from .graph import (check_lemma1, containment_pattern, laplacian, laplacian_blocks,
                    leader_tracking_matrix, unreachable_follower_message, unreachable_followers,
                    unreachable_leader_message, unreachable_leaders)

__all__ = [
    'Scenario', 'FaultSpec', 'ReferenceSpec', 'DisturbanceSpec', 'ImpairmentSpec', 'load_scenario', 'parse_scenario',
    'scenario_from_mapping', 'bundled_scenarios', 'read_config_file', 'CHANNEL_ALIASES', 'duration_steps',
]




# ------------------------------------------------------------------------------------------------
# Plain validated data


@dataclass(frozen=True, eq=False)
class ReferenceSpec:
    """Virtual-leader trajectory parameters (``uh_sim_node.reference.VirtualLeaderReference``).

    ``p0(t) = center + [radius sin(w t), -radius cos(w t), climb_rate t]``, ``w = angular_rate``
    rad/s; ``psi0(t) = initial_yaw + yaw_rate t``. Units m, rad/s, m, m/s, rad/s, rad.
    """

    radius: float
    angular_rate: float
    center: np.ndarray
    climb_rate: float
    yaw_rate: float
    initial_yaw: float = 0.0


@dataclass(frozen=True, eq=False)
class DisturbanceSpec:
    """Force disturbance ``d_p(t)`` on every UH, inertial frame.

    Per axis a: ``amplitude_a sin(frequency_a t + phase_a + i phase_per_id)`` N for UH ``i``.
    ``amplitude`` (3,) N, ``frequency`` (3,) rad/s, ``phase`` (3,) rad, ``phase_per_id`` rad.
    """

    amplitude: np.ndarray = field(default_factory=lambda: read_only_array(np.zeros(3)))
    frequency: np.ndarray = field(default_factory=lambda: read_only_array(np.zeros(3)))
    phase: np.ndarray = field(default_factory=lambda: read_only_array(np.zeros(3)))
    phase_per_id: float = 0.0

    @property
    def is_zero(self) -> bool:
        return not np.any(self.amplitude != 0.0)


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


#: :meth:`ImpairmentSpec.drop_step` of a UH that never drops out.
NO_DROPOUT = 2 ** 62


@dataclass(frozen=True, eq=False)
class Scenario:
    """A validated scenario (docs/graph.md, docs/scenario.md). Build it with :func:`load_scenario`.

    Attributes
    ----------
    name, description : str
    source : str or None
        File it was loaded from.
    dt : float
        Control period, s.
    duration : float
        s (``num_steps * dt``).
    substeps : int
        RK4 substeps per control period.
    settle_time : float
        s; metrics are taken after it.
    model_mismatch : float
        Factor applied to the controller's nominal ``D_v`` and ``c_Q``.
    helicopter : str
        Bundled helicopter parameter name (e.g. ``'helicopter'``) or absolute path of the file.
    leaders, followers, ids : tuple of int
        ``leaders = (1..N)``, ``followers = (N+1..N+M)``, ``ids = leaders + followers``.
    adjacency : ndarray (n+1, n+1)
        ``a_ij``: row i = what UH i hears, column 0 = virtual leader (read-only).
    offsets : mapping {leader id: ndarray (3,)}
        Formation offsets ``h_i``, m, inertial frame.
    initial_states : mapping {id: ndarray (12,)}
    faults : mapping {id: tuple of FaultSpec}
        Every UH id is a key (empty tuple when fault-free).
    reference : ReferenceSpec
    disturbance : DisturbanceSpec
    laplacian_blocks : (ndarray (M, M), ndarray (M, N))
        ``(L1, L2)``.
    containment_weights : ndarray (M, N)
        ``-L1^-1 L2``; rows follow ``followers``, columns ``leaders``.
    gains : dict
        Raw gains mapping (a fresh copy per access); read lazily from the file named by ``gains:``.
    impairments : ImpairmentSpec or None
        Communication and sensing impairments (docs/campaigns.md#impairments); None when the
        scenario has none or all of them are zero.
    """

    name: str
    description: str
    source: str | None
    dt: float
    duration: float
    substeps: int
    settle_time: float
    model_mismatch: float
    helicopter: str
    leaders: tuple
    followers: tuple
    adjacency: np.ndarray
    offsets: Mapping[int, np.ndarray]
    initial_states: Mapping[int, np.ndarray]
    faults: Mapping[int, tuple]
    reference: ReferenceSpec
    disturbance: DisturbanceSpec
    laplacian_blocks: tuple
    containment_weights: np.ndarray
    gains_source: Any = None  # inline mapping, or Path of the gains file
    impairments: ImpairmentSpec | None = None

    # -- roles and graph ----------------------------------------------------------------------
    @property
    def ids(self) -> tuple:
        """All UH ids, leaders first: ``(1, ..., N+M)``."""
        return self.leaders + self.followers

    @property
    def num_uhs(self) -> int:
        return len(self.leaders) + len(self.followers)

    @property
    def num_steps(self) -> int:
        """Number of control steps ``K = duration / dt``."""
        return int(round(self.duration / self.dt))

    def _check_id(self, i) -> int:
        if isinstance(i, bool) or not isinstance(i, (int, np.integer)) or not 1 <= i <= self.num_uhs:
            raise E.UnknownIdError(f'no UH with id {i!r}; ids are 1..{self.num_uhs}', source=self.source)
        return int(i)

    def is_leader(self, i: int) -> bool:
        return self._check_id(i) in self.leaders

    def role(self, i: int) -> str:
        """``'leader'`` or ``'follower'``."""
        return 'leader' if self.is_leader(i) else 'follower'

    def neighbours(self, i: int) -> tuple:
        """UH ids ``j >= 1`` that UH ``i`` hears (``a_ij > 0``), ascending."""
        i = self._check_id(i)
        return tuple(int(j) for j in np.nonzero(self.adjacency[i, 1:] > 0.0)[0] + 1)

    def weight(self, i: int, j: int) -> float:
        """``a_ij`` (``j = 0``: the virtual-leader link)."""
        i = self._check_id(i)
        if j != 0:
            j = self._check_id(j)
        return float(self.adjacency[i, j])

    def leader_link(self, i: int) -> float:
        """``a_i0``: weight with which UH ``i`` hears the virtual leader (0 if it does not)."""
        return float(self.adjacency[self._check_id(i), 0])

    def degree(self, i: int) -> float:
        """``d_i = sum_j a_ij + a_i0`` (docs/graph.md)."""
        return float(self.adjacency[self._check_id(i)].sum())

    @property
    def laplacian(self) -> np.ndarray:
        """``L = D - A`` (n, n) over the UHs (no virtual-leader column)."""
        return laplacian(self.adjacency)

    @property
    def leader_tracking_matrix(self) -> np.ndarray:
        """``L[L, L] + diag(a_i0)`` (N, N)."""
        return leader_tracking_matrix(self.adjacency, self.leaders)

    def containment_weight_rows(self) -> dict:
        """``{follower id: {leader id: weight}}`` of ``-L1^-1 L2``."""
        return {k: {j: float(self.containment_weights[r, c]) for c, j in enumerate(self.leaders)}
                for r, k in enumerate(self.followers)}

    # -- gains ----------------------------------------------------------------------------------
    @property
    def gains(self) -> dict:
        """Raw gains mapping (copy), from the inline mapping or the file named by ``gains:``."""
        if 'gains_cache' not in self.__dict__:
            self.__dict__['gains_cache'] = _load_gains(self.gains_source, self.source)
        return copy.deepcopy(self.__dict__['gains_cache'])

    @property
    def gains_path(self) -> Path | None:
        """Path of the gains file, ``None`` for inline gains."""
        return self.gains_source if isinstance(self.gains_source, Path) else None

    def __repr__(self) -> str:
        return (f'Scenario(name={self.name!r}, leaders={self.leaders}, followers={self.followers}, '
                f'dt={self.dt}, duration={self.duration}, source={self.source!r})')


def _load_gains(src, scenario_source) -> dict:
    if src is None:
        return {}
    if isinstance(src, Mapping):
        return dict(src)
    path = Path(src)
    try:
        text = path.read_text()
    except OSError as exc:
        raise E.GainsFileError(f'cannot read the gains file {str(path)!r} ({exc.strerror}); `gains:` must '
                           f'name an existing YAML file relative to the scenario file or be a mapping',
                           source=scenario_source, path='gains') from None
    data, _ = parse_yaml(text, str(path))   # a repeated key is an error, with its line, as in a scenario
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise E.GainsFileError(f'the gains file must hold a mapping, got {type(data).__name__}',
                           source=str(path))
    return data


# ------------------------------------------------------------------------------------------------
# Building a Scenario

_TOP_REQUIRED = ('name', 'dt', 'duration', 'uhs', 'edges', 'reference_links', 'reference')
_TOP_OPTIONAL = ('description', 'substeps', 'settle_time', 'model_mismatch', 'helicopter', 'gains',
                 'disturbance', 'faults', 'impairments')
_UH_REQUIRED = ('id', 'role', 'initial_state')
_UH_OPTIONAL = ('offset',)
_STATE_REQUIRED = ('position',)
_STATE_OPTIONAL = ('velocity', 'euler', 'omega')
_REF_REQUIRED = ('radius', 'angular_rate', 'center', 'climb_rate', 'yaw_rate')
_REF_OPTIONAL = ('initial_yaw',)
_DIST_OPTIONAL = ('amplitude', 'frequency', 'phase', 'phase_per_id')
_FAULT_REQUIRED = ('uh', 'channel', 'rho')
_FAULT_OPTIONAL = ('bias_constant', 'bias_amplitude', 'bias_frequency', 'onset_time')
_IMPAIRMENT_OPTIONAL = ('seed', 'delay_steps', 'jitter_steps', 'loss', 'links', 'noise', 'dropouts',
                        'delay_compensation')
_LINK_OPTIONAL = ('delay_steps', 'jitter_steps', 'loss')
#: The values of ``impairments.delay_compensation``: states used as received, or predicted to the current step.
COMPENSATIONS = ('none', 'predict')
#: ``impairments.delay_compensation`` when the key is absent (docs/delay.md says why).
DEFAULT_COMPENSATION = 'predict'
_NOISE_KEYS = (('position', 'm'), ('velocity', 'm/s'), ('attitude', 'rad'), ('rate', 'rad/s'))

DEFAULT_SUBSTEPS = 5
DEFAULT_SETTLE_TIME = 20.0
DEFAULT_MODEL_MISMATCH = 0.9
DEFAULT_HELICOPTER = 'helicopter'


@dataclass(frozen=True)
class _Timing:
    """The scalar entries of a scenario: names and times (s)."""

    name: str
    description: str
    dt: float
    substeps: int
    duration: float
    settle_time: float
    model_mismatch: float


@dataclass(frozen=True)
class _Team:
    """The UHs of a scenario: roles, offsets, initial states and where each is listed."""

    roles: dict      # id -> 'leader' | 'follower'
    offsets: dict    # leader id -> (3,) m
    states: dict     # id -> (12,)
    where: dict      # id -> index in `uhs`
    leaders: tuple
    followers: tuple


def scenario_from_mapping(data, *, source: str | None = None, base_dir=None,
                          lines: dict | None = None) -> Scenario:
    """Validate a scenario mapping (as read from YAML) and build the :class:`Scenario`.

    The checks run in this order, and the first that fails raises: the entries' schema and
    timing, the file names (helicopter, gains), the UHs, the graph, Assumption 1 and Lemma 1, the
    reference, the disturbance, the faults, the impairments.

    Parameters
    ----------
    data : dict
    source : str, optional
        Name used in error messages.
    base_dir : path, optional
        Directory for relative ``gains`` / ``helicopter`` paths (default: current directory).
    lines : dict, optional
        Key path -> line map (from the YAML parser) for error messages.
    """
    ctx = ConfigContext(source, lines or {})
    base = Path(base_dir) if base_dir is not None else Path.cwd()
    top = ctx.mapping(data, (), _TOP_REQUIRED, _TOP_OPTIONAL, what='a scenario mapping')
    timing = _timing(ctx, top)
    helicopter = _helicopter(ctx, top, base)
    gains_source = _gains_source(ctx, top, base)
    team = _team(ctx, top['uhs'])
    adjacency = np.zeros((len(team.roles) + 1, len(team.roles) + 1))
    _edges(ctx, top['edges'], team, adjacency)
    _reference_links(ctx, top['reference_links'], team, adjacency)
    l1, l2, weights = _assumptions(ctx, adjacency, team)
    reference = _reference(ctx, top['reference'])
    disturbance = _disturbance(ctx, top.get('disturbance') or {})
    faults = _faults(ctx, top.get('faults') or [], team)
    impairments = (_impairments(ctx, top['impairments'], adjacency, set(team.roles), timing.duration)
                   if top.get('impairments') is not None else None)
    if impairments is not None and not impairments.is_active:
        impairments = None   # all zero: the run without impairments (any clock, no /uhN/received)

    adjacency.setflags(write=False)
    return Scenario(
        name=timing.name, description=timing.description, source=source, dt=timing.dt,
        duration=timing.duration, substeps=timing.substeps, settle_time=timing.settle_time,
        model_mismatch=timing.model_mismatch, helicopter=helicopter,
        leaders=team.leaders, followers=team.followers, adjacency=adjacency,
        offsets=MappingProxyType(dict(sorted(team.offsets.items()))),
        initial_states=MappingProxyType(dict(sorted(team.states.items()))),
        faults=MappingProxyType({i: tuple(sorted(f, key=lambda s: s.channel)) for i, f in faults.items()}),
        reference=reference, disturbance=disturbance,
        laplacian_blocks=(read_only_array(l1), read_only_array(l2)),
        containment_weights=read_only_array(weights), gains_source=gains_source, impairments=impairments,
    )


def duration_steps(duration, dt: float) -> int:
    """Return the control steps of a run of ``duration`` s at control period ``dt`` s.

    The one rule for a duration, wherever it is given (a scenario or campaign file, ``--duration``
    of ``run_formation.sh`` and ``uh-simulate``): a finite number of seconds, at least one control
    period, and a whole number of them (to a relative 1e-9, the rounding of decimal seconds).

    Raises
    ------
    ValueError
        With the reason and what is allowed, worded to follow the name of the duration.
    """
    if isinstance(duration, bool) or not isinstance(duration, (int, float)) or not math.isfinite(duration):
        raise ValueError(f'{duration!r} is not a finite number of seconds; allowed: a multiple of dt = {dt} s')
    steps = round(duration / dt)
    if steps < 1:
        raise ValueError(f'{duration:g} s is shorter than one control period dt = {dt} s; allowed: a multiple of dt')
    if abs(steps * dt - duration) > 1e-9 * max(1.0, duration):
        raise ValueError(f'{duration} s is not a whole number of control periods dt = {dt} s; '
                         'allowed: a multiple of dt')
    return steps


def _timing(ctx: ConfigContext, top: dict) -> _Timing:
    """Read the name, description, control period, substeps, duration, settle time and mismatch."""
    name = ctx.string(top['name'], ('name',))
    description = ctx.string(top.get('description', ''), ('description',))
    dt = ctx.number(top['dt'], ('dt',), lo=0.0, lo_open=True, unit='s')
    substeps = ctx.integer(top.get('substeps', DEFAULT_SUBSTEPS), ('substeps',), lo=1)
    duration = ctx.number(top['duration'], ('duration',), lo=dt, unit='s')
    try:
        duration_steps(duration, dt)
    except ValueError as exc:
        raise ctx.error(E.InvalidValueError, ('duration',), f'duration {exc}') from None
    settle = ctx.number(top.get('settle_time', DEFAULT_SETTLE_TIME), ('settle_time',), lo=0.0,
                        hi=duration, hi_open=True, unit='s')
    mismatch = ctx.number(top.get('model_mismatch', DEFAULT_MODEL_MISMATCH), ('model_mismatch',),
                          lo=0.0, lo_open=True)
    return _Timing(name=name, description=description, dt=dt, substeps=substeps, duration=duration,
                   settle_time=settle, model_mismatch=mismatch)


def _helicopter(ctx: ConfigContext, top: dict, base: Path) -> str:
    """Give the helicopter entry: a bundled name as written, a file name resolved against ``base``."""
    helicopter = ctx.string(top.get('helicopter', DEFAULT_HELICOPTER), ('helicopter',))
    if not helicopter:
        raise ctx.error(E.InvalidValueError, ('helicopter',), 'empty helicopter name; allowed: a bundled '
                        'name (e.g. helicopter) or a path to a YAML file')
    hp = Path(helicopter)
    if hp.suffix or hp.parent != Path('.'):
        helicopter = str((base / hp).resolve()) if not hp.is_absolute() else str(hp)
    return helicopter


def _gains_source(ctx: ConfigContext, top: dict, base: Path):
    """Give the gains entry: None, a read-only copy of an inline mapping, or the resolved file path."""
    gains_raw = top.get('gains')
    if gains_raw is None:
        return None
    if isinstance(gains_raw, dict):
        return MappingProxyType(copy.deepcopy(gains_raw))
    if isinstance(gains_raw, str) and gains_raw:
        return Path(gains_raw) if Path(gains_raw).is_absolute() else (base / gains_raw).resolve()
    raise ctx.error(E.WrongTypeError, ('gains',),
                    f'expected a file name (relative to the scenario) or a mapping, got {type_name(gains_raw)}')


def _team(ctx: ConfigContext, uhs) -> _Team:
    """Read the ``uhs`` list and check the numbering: ids 1..N+M, leaders first, leaders with offsets."""
    if not isinstance(uhs, list) or not uhs:
        raise ctx.error(E.WrongTypeError, ('uhs',), f'expected a non-empty list of UHs, got {type_name(uhs)}')
    roles, offsets, states, where = {}, {}, {}, {}
    for idx, entry in enumerate(uhs):
        path = ('uhs', idx)
        ctx.mapping(entry, path, _UH_REQUIRED, _UH_OPTIONAL, what='a UH mapping')
        uid = ctx.integer(entry['id'], path + ('id',), what='an integer UH id')
        if uid in roles:
            raise ctx.error(E.DuplicateIdError, path + ('id',),
                            f'UH id {uid} is already used by uhs[{where[uid]}]; ids must be unique')
        if uid < 1:
            raise ctx.error(E.IdNumberingError, path + ('id',),
                            f'UH id {uid} is not allowed; 0 is the virtual leader, UH ids are 1..N+M')
        where[uid] = idx
        roles[uid] = ctx.string(entry['role'], path + ('role',), choices=('leader', 'follower'))
        states[uid] = _initial_state(ctx, entry['initial_state'], path + ('initial_state',))
        if 'offset' in entry:
            if roles[uid] == 'follower':
                raise ctx.error(E.FollowerOffsetError, path + ('offset',),
                                f'follower {uid} has a formation offset; only leaders have offsets '
                                f'(followers are placed by the containment weights)')
            offsets[uid] = ctx.vector(entry['offset'], path + ('offset',), unit='m')

    n = len(roles)
    leaders = tuple(sorted(i for i, r in roles.items() if r == 'leader'))
    followers = tuple(sorted(i for i, r in roles.items() if r == 'follower'))
    if not leaders:
        raise ctx.error(E.IdNumberingError, ('uhs',), 'no leader; at least one UH must have role: leader')
    if set(roles) != set(range(1, n + 1)) or leaders != tuple(range(1, len(leaders) + 1)):
        raise ctx.error(E.IdNumberingError, ('uhs',),
                        f'ids must be 1..{n} with the leaders first; got leaders {list(leaders)} and '
                        f'followers {list(followers)}')
    for j in leaders:
        if j not in offsets:
            raise ctx.error(E.MissingOffsetError, ('uhs', where[j]),
                            f'leader {j} has no formation offset; add offset: [x, y, z] (m)')
    return _Team(roles=roles, offsets=offsets, states=states, where=where, leaders=leaders, followers=followers)


def _initial_state(ctx: ConfigContext, raw, sp: tuple) -> np.ndarray:
    """Read an ``initial_state`` mapping as the (12,) state: position m, velocity m/s, Euler rad, rate rad/s."""
    st = ctx.mapping(raw, sp, _STATE_REQUIRED, _STATE_OPTIONAL, what='an initial_state mapping')
    pos = ctx.vector(st['position'], sp + ('position',), unit='m')
    vel = ctx.vector(st.get('velocity', [0.0] * 3), sp + ('velocity',), unit='m/s')
    eul = ctx.vector(st.get('euler', [0.0] * 3), sp + ('euler',), unit='rad')
    omg = ctx.vector(st.get('omega', [0.0] * 3), sp + ('omega',), unit='rad/s')
    for axis, lim in ((0, math.pi / 2), (1, math.pi / 2)):
        if abs(eul[axis]) >= lim:
            raise ctx.error(E.InvalidValueError, sp + ('euler', axis),
                            f'{("roll", "pitch")[axis]} {eul[axis]} rad; allowed: |angle| < pi/2')
    return read_only_array(np.concatenate([pos, vel, eul, omg]))


def _edges(ctx: ConfigContext, edges, team: _Team, adjacency: np.ndarray) -> None:
    """Read the ``edges`` list into ``adjacency[i, j] = a_ij`` (UH i hears UH j)."""
    roles, known = team.roles, set(team.roles)
    if edges is None:
        edges = []
    if not isinstance(edges, list):
        raise ctx.error(E.WrongTypeError, ('edges',), f'expected a list of edges, got {type_name(edges)}')
    edge_at = {}
    for idx, edge in enumerate(edges):
        path = ('edges', idx)
        ctx.mapping(edge, path, ('uh', 'hears'), ('weight',), what='an edge mapping {uh, hears, weight}')
        i = ctx.uh_id(edge['uh'], path + ('uh',), known)
        j = ctx.uh_id(edge['hears'], path + ('hears',), known)
        if i == j:
            raise ctx.error(E.SelfLoopError, path, f'UH {i} hears itself (self-loop); an edge must join '
                            f'two different UHs')
        w = ctx.number(edge.get('weight', 1.0), path + ('weight',))
        if w < 0.0:
            raise ctx.error(E.NegativeWeightError, path + ('weight',),
                            f'negative weight {w} on edge {i}<-{j}; allowed: a weight >= 0')
        if (i, j) in edge_at:
            raise ctx.error(E.DuplicateEdgeError, path,
                            f'edge {i}<-{j} is already listed as edges[{edge_at[(i, j)]}]; list each '
                            f'directed edge once')
        if roles[i] == 'leader' and roles[j] == 'follower' and w > 0.0:
            raise ctx.error(E.LeaderHearsFollowerError, path,
                            f'leader {i} hears follower {j}; leaders may only hear leaders and the '
                            f'virtual leader')
        edge_at[(i, j)] = idx
        adjacency[i, j] = w


def _reference_links(ctx: ConfigContext, links, team: _Team, adjacency: np.ndarray) -> None:
    """Read the ``reference_links`` list into ``adjacency[i, 0] = a_i0`` (UH i hears the virtual leader)."""
    roles, known = team.roles, set(team.roles)
    if links is None:
        links = []
    if not isinstance(links, list):
        raise ctx.error(E.WrongTypeError, ('reference_links',),
                        f'expected a list of links {{uh, weight}}, got {type_name(links)}')
    link_at = {}
    for idx, link in enumerate(links):
        path = ('reference_links', idx)
        ctx.mapping(link, path, ('uh',), ('weight',), what='a link mapping {uh, weight}')
        i = ctx.uh_id(link['uh'], path + ('uh',), known)
        w = ctx.number(link.get('weight', 1.0), path + ('weight',))
        if w < 0.0:
            raise ctx.error(E.NegativeWeightError, path + ('weight',),
                            f'negative weight {w} on the virtual-leader link {i}<-0; allowed: a weight >= 0')
        if i in link_at:
            raise ctx.error(E.DuplicateEdgeError, path,
                            f'virtual-leader link {i}<-0 is already listed as reference_links'
                            f'[{link_at[i]}]; list each link once')
        if roles[i] == 'follower' and w > 0.0:
            raise ctx.error(E.FollowerLinkedToReferenceError, path + ('uh',),
                            f'follower {i} hears the virtual leader; only leaders may (followers '
                            f'are contained by the leaders)')
        link_at[i] = idx
        adjacency[i, 0] = w


def _assumptions(ctx: ConfigContext, adjacency: np.ndarray, team: _Team) -> tuple:
    """Check Assumption 1 and Lemma 1 (docs/graph.md); give ``(L1, L2, -L1^-1 L2)``.

    An unreachable UH is reported at its entry under ``uhs`` (the first one without a path).
    """
    leaders, followers, where = team.leaders, team.followers, team.where
    lost = unreachable_leaders(adjacency, leaders)
    if lost:
        raise ctx.error(E.UnreachableLeaderError, ('uhs', where[lost[0]]), unreachable_leader_message(lost),
                        ids=lost)
    lost = unreachable_followers(adjacency, leaders, followers)
    if lost:
        raise ctx.error(E.UnreachableFollowerError, ('uhs', where[lost[0]]),
                        unreachable_follower_message(lost), ids=lost)
    l1, l2 = laplacian_blocks(adjacency, leaders, followers)
    try:  # Lemma 1 (implied by Assumption 1; checked numerically as a guard)
        weights = check_lemma1(l1, l2, containment_pattern(adjacency, leaders, followers))
    except E.LaplacianConditionError as exc:
        raise ctx.error(E.LaplacianConditionError, ('edges',), exc.message) from None
    return l1, l2, weights


def _reference(ctx: ConfigContext, raw) -> ReferenceSpec:
    """Read the ``reference`` mapping (the virtual leader's trajectory)."""
    rp = ('reference',)
    ref = ctx.mapping(raw, rp, _REF_REQUIRED, _REF_OPTIONAL, what='a reference mapping')
    return ReferenceSpec(
        radius=ctx.number(ref['radius'], rp + ('radius',), lo=0.0, unit='m'),
        angular_rate=ctx.number(ref['angular_rate'], rp + ('angular_rate',), unit='rad/s'),
        center=ctx.vector(ref['center'], rp + ('center',), unit='m'),
        climb_rate=ctx.number(ref['climb_rate'], rp + ('climb_rate',), unit='m/s'),
        yaw_rate=ctx.number(ref['yaw_rate'], rp + ('yaw_rate',), unit='rad/s'),
        initial_yaw=ctx.number(ref.get('initial_yaw', 0.0), rp + ('initial_yaw',), unit='rad'),
    )


def _disturbance(ctx: ConfigContext, dist) -> DisturbanceSpec:
    """Read the ``disturbance`` mapping (empty: no disturbance)."""
    dp = ('disturbance',)
    ctx.mapping(dist, dp, (), _DIST_OPTIONAL, what='a disturbance mapping')
    disturbance = DisturbanceSpec(
        amplitude=ctx.vector(dist.get('amplitude', [0.0] * 3), dp + ('amplitude',), unit='N'),
        frequency=ctx.vector(dist.get('frequency', [0.0] * 3), dp + ('frequency',), unit='rad/s'),
        phase=ctx.vector(dist.get('phase', [0.0] * 3), dp + ('phase',), unit='rad'),
        phase_per_id=ctx.number(dist.get('phase_per_id', 0.0), dp + ('phase_per_id',), unit='rad'),
    )
    if np.any(disturbance.amplitude < 0.0):
        raise ctx.error(E.InvalidValueError, dp + ('amplitude',),
                        f'negative amplitude {disturbance.amplitude.tolist()}; allowed: >= 0 N '
                        f'(use the phase for the sign)')
    return disturbance


def _faults(ctx: ConfigContext, faults_raw, team: _Team) -> dict:
    """Read the ``faults`` list as ``{uh id: [FaultSpec, ...]}`` with every id a key, one fault per channel."""
    if not isinstance(faults_raw, list):
        raise ctx.error(E.WrongTypeError, ('faults',), f'expected a list of faults, got {type_name(faults_raw)}')
    known = set(team.roles)
    faults = {i: [] for i in range(1, len(team.roles) + 1)}
    fault_at = {}
    for idx, fd in enumerate(faults_raw):
        path = ('faults', idx)
        ctx.mapping(fd, path, _FAULT_REQUIRED, _FAULT_OPTIONAL, what='a fault mapping')
        i = ctx.uh_id(fd['uh'], path + ('uh',), known)
        ch = ctx.channel(fd['channel'], path + ('channel',))
        if (i, ch) in fault_at:
            raise ctx.error(E.DuplicateFaultError, path + ('channel',),
                            f'UH {i} channel {ch} already has a fault (faults[{fault_at[(i, ch)]}]); '
                            f'one fault per channel')
        fault_at[(i, ch)] = idx
        faults[i].append(FaultSpec(
            channel=ch,
            rho=ctx.number(fd['rho'], path + ('rho',), lo=0.0, hi=1.0),
            bias_constant=ctx.number(fd.get('bias_constant', 0.0), path + ('bias_constant',), unit='rad'),
            bias_amplitude=ctx.number(fd.get('bias_amplitude', 0.0), path + ('bias_amplitude',), unit='rad'),
            bias_frequency=ctx.number(fd.get('bias_frequency', 0.0), path + ('bias_frequency',), unit='rad/s'),
            onset_time=ctx.number(fd.get('onset_time', 0.0), path + ('onset_time',), lo=0.0, unit='s'),
        ))
    return faults


def _impairments(ctx, raw, adjacency, known, duration) -> ImpairmentSpec:
    """Validate the ``impairments`` mapping (docs/campaigns.md#impairments) against the graph."""
    path = ('impairments',)
    ctx.mapping(raw, path, (), _IMPAIRMENT_OPTIONAL, what='an impairments mapping')
    seed = ctx.integer(raw.get('seed', 0), path + ('seed',), lo=0, what='an integer seed >= 0')
    compensation = ctx.string(raw.get('delay_compensation', DEFAULT_COMPENSATION), path + ('delay_compensation',),
                              choices=COMPENSATIONS)
    edges = [(int(i), int(j) + 1) for i, j in zip(*np.nonzero(adjacency[:, 1:] > 0.0))]   # (uh, hears)
    per_link = {key: dict.fromkeys(edges, _link_value(ctx, raw, path, key, 0)) for key in _LINK_OPTIONAL}
    links = raw.get('links') or []
    if not isinstance(links, list):
        raise ctx.error(E.WrongTypeError, path + ('links',), f'expected a list of links, got {type_name(links)}')
    for idx, link in enumerate(links):
        lp = path + ('links', idx)
        ctx.mapping(link, lp, ('uh', 'hears'), _LINK_OPTIONAL,
                    what='a link mapping {uh, hears, delay_steps, jitter_steps, loss}')
        i = ctx.uh_id(link['uh'], lp + ('uh',), known)
        j = ctx.uh_id(link['hears'], lp + ('hears',), known)
        if (i, j) not in per_link['loss']:
            raise ctx.error(E.InvalidValueError, lp, f'UH {i} does not hear UH {j}: no such edge in `edges`; '
                            f'impairments act on existing links only')
        for key in _LINK_OPTIONAL:
            if key in link:
                per_link[key][(i, j)] = _link_value(ctx, link, lp, key, None)
    noise_raw = raw.get('noise') or {}
    ctx.mapping(noise_raw, path + ('noise',), (), tuple(k for k, _ in _NOISE_KEYS), what='a noise mapping')
    noise = np.concatenate([np.full(3, ctx.number(noise_raw.get(key, 0.0), path + ('noise', key), lo=0.0, unit=unit))
                            for key, unit in _NOISE_KEYS])
    dropouts = {}
    drops = raw.get('dropouts') or []
    if not isinstance(drops, list):
        raise ctx.error(E.WrongTypeError, path + ('dropouts',), f'expected a list of dropouts, got {type_name(drops)}')
    for idx, drop in enumerate(drops):
        dp = path + ('dropouts', idx)
        ctx.mapping(drop, dp, ('uh', 'time'), (), what='a dropout mapping {uh, time}')
        i = ctx.uh_id(drop['uh'], dp + ('uh',), known)
        if i in dropouts:
            raise ctx.error(E.InvalidValueError, dp + ('uh',), f'UH {i} already drops out; one dropout per UH')
        dropouts[i] = ctx.number(drop['time'], dp + ('time',), lo=0.0, hi=duration, unit='s')
    return ImpairmentSpec(seed=seed, delays=MappingProxyType(per_link['delay_steps']),
                          losses=MappingProxyType(per_link['loss']), noise=read_only_array(noise),
                          dropouts=MappingProxyType(dropouts), jitters=MappingProxyType(per_link['jitter_steps']),
                          compensation=compensation)


def _link_value(ctx, raw, path, key, default):
    """Read a link setting ``key`` (one of :data:`_LINK_OPTIONAL`) of mapping ``raw`` at ``path``."""
    value = raw.get(key, default)
    if key == 'loss':
        return ctx.number(0.0 if value is None else value, path + (key,), lo=0.0, hi=1.0, hi_open=True)
    return ctx.integer(0 if value is None else value, path + (key,), lo=0, what='a whole number of steps >= 0')


def parse_scenario(text: str, *, source: str | None = None, base_dir=None) -> Scenario:
    """Parse and validate scenario YAML text (``base_dir`` resolves relative file names)."""
    data, lines = parse_yaml(text, source)
    if data is None:
        raise E.MissingFieldError('the scenario is empty; required keys: ' + ', '.join(_TOP_REQUIRED),
                                  source=source)
    return scenario_from_mapping(data, source=source, base_dir=base_dir, lines=lines)


def bundled_scenarios() -> tuple:
    """Names of the scenarios bundled in ``uh_topology/config`` (e.g. ``('paper',)``)."""
    return tuple(sorted(p.stem for p in CONFIG_DIR.glob('*.yaml')
                        if not p.stem.endswith('_gains') and not p.stem.startswith('campaign_')))


def load_scenario(path_or_name) -> Scenario:
    """Load and validate a scenario.

    Parameters
    ----------
    path_or_name : str or Path
        A YAML file, or the name of a bundled scenario (``'paper'`` ->
        ``uh_topology/config/paper.yaml``).

    Raises
    ------
    ScenarioNotFoundError
        Neither an existing file nor a bundled name.
    ScenarioError
        Any of the specific subclasses of :mod:`uh_topology.errors`.
    """
    if isinstance(path_or_name, Scenario):
        return path_or_name
    path, content = read_config_file(path_or_name, 'scenario', bundled_scenarios)
    return parse_scenario(content, source=str(path), base_dir=path.resolve().parent)
