"""Scenario loading and validation: team, communication graph, faults, reference (docs/graph.md, docs/scenario.md).

A scenario is one YAML file (see ``uh_topology/config/paper.yaml`` for a commented example)::

    name: paper
    dt: 0.01                    # control period, s
    duration: 60.0              # s, a multiple of dt
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
    impairments: {delay_steps: 2, loss: 0.1}   # optional; what the controllers receive

The top-level keys and those of ``impairments`` (which are required, their defaults, units and
ranges) are declared once, in :mod:`uh_topology.scenario_keys`; the impairments are read by
:mod:`uh_topology.impairments`. Validation raises the specific :mod:`uh_topology.errors` types with
the file, line and key path.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np

from uh_core.airframe import HelicopterParamsError, load_helicopter_params
from uh_core.layout import CHANNEL_ALIASES
from uh_core.records import FaultSpec

from . import errors as E
from . import scenario_keys
from .events import ResilienceSpec, read_events, read_resilience
from .graph import laplacian, leader_tracking_matrix
from .impairments import COMPENSATIONS, DEFAULT_COMPENSATION, NO_DROPOUT, ImpairmentSpec, read_impairments
from .reform import ReformedTeam, bypass_standby_edges, declared_edges, reformed_team
from .safety import SafetySpec, close_pairs, formation_points, read_safety
from .scenario_keys import SCENARIO_KEYS, key_named, key_names, read_key
from .scenario_team import Team, check_assumptions, read_edges, read_reference_links, read_team
from .schema import CONFIG_DIR, ConfigContext, parse_yaml, read_config_file, read_only_array, read_text_file, type_name

__all__ = [
    'Scenario', 'FaultSpec', 'ReferenceSpec', 'DisturbanceSpec', 'ImpairmentSpec', 'load_scenario', 'parse_scenario',
    'scenario_from_mapping', 'bundled_scenarios', 'read_config_file', 'CHANNEL_ALIASES', 'duration_steps',
    'NO_DROPOUT', 'COMPENSATIONS', 'DEFAULT_COMPENSATION', 'DEFAULT_SUBSTEPS', 'DEFAULT_SETTLE_TIME',
    'DEFAULT_MODEL_MISMATCH', 'DEFAULT_HELICOPTER',
]




# ------------------------------------------------------------------------------------------------
# Plain validated data


@dataclass(frozen=True, eq=False)
class ReferenceSpec:
    """Virtual-leader trajectory parameters (``uh_core.reference.VirtualLeaderReference``).

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
        """Whether every amplitude is 0 (no disturbance at all)."""
        return not np.any(self.amplitude != 0.0)


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
    safety : SafetySpec
        The collision-avoidance layer's settings (docs/safety.md).
    reference_links_rule : str or None
        ``'all_leaders'`` when ``reference_links`` named that rule (a departure from the paper's graph,
        docs/delay.md#remedies); None for a list.
    separation_warnings : tuple of SeparationIssue
        Formation targets or initial positions closer than ``min_separation`` (but not than two
        rotor radii, which is an error): the run says so at start (docs/safety.md#design-time-check).
    events : tuple of TeamEvent
        What happens to the team during the run, by time (docs/resilience.md); empty: nothing.
    resilience : ResilienceSpec or None
        How the team answers a loss, as the file gives it (None: not given; :attr:`loss_answer`
        gives the defaults then).
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
    safety: SafetySpec = SafetySpec()
    separation_warnings: tuple = ()
    reference_links_rule: str | None = None
    events: tuple = ()
    resilience: ResilienceSpec | None = None

    # -- roles and graph ----------------------------------------------------------------------
    @property
    def ids(self) -> tuple:
        """All UH ids, leaders first: ``(1, ..., N+M)``."""
        return self.leaders + self.followers

    @property
    def num_uhs(self) -> int:
        """Number of UHs ``N + M`` (leaders and followers)."""
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
        """Return whether UH ``i`` is a leader; :class:`~uh_topology.errors.UnknownIdError` for an id not in 1..N+M."""
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

    # -- losses (docs/resilience.md) -----------------------------------------------------------
    def standby_edges(self) -> tuple:
        """Give the standby edges ``(uh, hears)`` (``hears = 0``: the virtual leader), sorted."""
        spec = self.resilience
        if spec is None or spec.standby == 'none':
            return ()
        if spec.standby == 'bypass':
            return bypass_standby_edges(self)
        return tuple(spec.standby)

    def receivable_edges(self) -> set:
        """Every edge ``(uh, hears)`` a UH can receive: the declared ones and the standby ones."""
        return declared_edges(self) | set(self.standby_edges())

    def reformed(self, lost) -> ReformedTeam:
        """Give the team every UH computes without the UHs ``lost`` (:func:`uh_topology.reform.reformed_team`)."""
        return reformed_team(self, lost, self.receivable_edges())

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
        text = read_text_file(path)
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

_REF_REQUIRED = ('radius', 'angular_rate', 'center', 'climb_rate', 'yaw_rate')
_REF_OPTIONAL = ('initial_yaw',)
_DIST_OPTIONAL = ('amplitude', 'frequency', 'phase', 'phase_per_id')
_FAULT_REQUIRED = ('uh', 'channel', 'rho')
_FAULT_OPTIONAL = ('bias_constant', 'bias_amplitude', 'bias_frequency', 'onset_time')

# The defaults of the top-level keys, as declared in uh_topology.scenario_keys.SCENARIO_KEYS.
DEFAULT_SUBSTEPS = key_named(SCENARIO_KEYS, 'substeps').default
DEFAULT_SETTLE_TIME = key_named(SCENARIO_KEYS, 'settle_time').default
DEFAULT_MODEL_MISMATCH = key_named(SCENARIO_KEYS, 'model_mismatch').default
DEFAULT_HELICOPTER = key_named(SCENARIO_KEYS, 'helicopter').default


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
    keys = scenario_keys.SCENARIO_KEYS
    top = ctx.mapping(data, (), key_names(keys, required=True), key_names(keys, required=False),
                      what='a scenario mapping')
    timing = _timing(ctx, top)
    helicopter = _helicopter(ctx, top, base)
    gains_source = _gains_source(ctx, top, base)
    team = read_team(ctx, top['uhs'])
    adjacency = np.zeros((len(team.roles) + 1, len(team.roles) + 1))
    read_edges(ctx, top['edges'], team, adjacency)
    reference_rule = read_reference_links(ctx, top['reference_links'], team, adjacency)
    l1, l2, weights = check_assumptions(ctx, adjacency, team)
    reference = _reference(ctx, top['reference'])
    disturbance = _disturbance(ctx, top.get('disturbance') or {})
    faults = _faults(ctx, top.get('faults') or [], team)
    impairments = (read_impairments(ctx, top['impairments'], adjacency, set(team.roles), timing.duration)
                   if top.get('impairments') is not None else None)
    if impairments is not None and not impairments.is_active:
        impairments = None   # all zero: the run without impairments (any clock, no /uhN/received)
    safety = read_safety(ctx, top.get('safety'))
    warnings = _separable(ctx, helicopter, safety, team, weights)
    events = read_events(ctx, top.get('events'), set(team.roles), timing.dt, timing.duration)
    link_age = (max((impairments.delays[e] + impairments.jitters[e] for e in impairments.delays), default=0)
                * timing.dt if impairments is not None else 0.0)
    checks = dict(dt=timing.dt, worst_loss=max(impairments.losses.values(), default=0.0) if impairments else 0.0,
                  dropouts=bool(impairments.dropouts) if impairments else False)
    resilience = read_resilience(ctx, top.get('resilience'), adjacency, set(team.roles), link_age, **checks)
    if resilience is None and events:     # the defaults, checked
        resilience = read_resilience(ctx, {}, adjacency, set(team.roles), link_age, **checks)

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
        safety=safety, separation_warnings=warnings, reference_links_rule=reference_rule, events=events,
        resilience=resilience,
    )


def _separable(ctx: ConfigContext, helicopter: str, safety: SafetySpec, team, weights) -> tuple:
    """Check the formation targets and initial positions pairwise (docs/safety.md#design-time-check).

    Closer than two rotor radii raises when the filter is enabled (it cannot keep such a pair apart
    where the law sends it) and is a warning otherwise (the paper's law alone, as it was published);
    closer than the minimum separation is a warning. An airframe file that does not load is left to
    the check that loads it for the run.
    """
    try:
        rotor_radius = load_helicopter_params(helicopter).rotor_radius
    except HelicopterParamsError:
        return ()
    separation = safety.separation(rotor_radius)
    if separation < 2.0 * rotor_radius:
        raise ctx.error(E.InvalidValueError, ('safety', 'min_separation'), f'min_separation {separation:g} m is below '
                        f'two rotor radii of the airframe; allowed: >= {2.0 * rotor_radius:g} m')
    if safety.sensing_radius <= separation:
        raise ctx.error(E.InvalidValueError, ('safety', 'sensing_radius'), f'sensing_radius {safety.sensing_radius:g} '
                        f'm is not beyond the minimum separation {separation:g} m; allowed: > {separation:g} m')
    leaders = tuple(sorted(k for k, role in team.roles.items() if role == 'leader'))
    followers = tuple(sorted(k for k, role in team.roles.items() if role != 'leader'))
    places = {'formation': formation_points(leaders, followers, team.offsets, weights),
              'initial': {i: state[:3] for i, state in team.states.items()}}
    warnings = []
    for what, points in places.items():
        overlapping = close_pairs(points, 2.0 * rotor_radius, what)
        if overlapping and safety.enabled:
            raise ctx.error(E.InvalidValueError, ('uhs', team.where[overlapping[0].second]),
                            f'{overlapping[0].text()}: closer than two rotor radii ({2.0 * rotor_radius:g} m, the '
                            f'rotor disks overlap); allowed: >= {2.0 * rotor_radius:g} m')
        warnings += close_pairs(points, separation, what)
    return tuple(warnings)


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
    def read(name, **bounds):
        return read_key(ctx, key_named(scenario_keys.SCENARIO_KEYS, name), top, **bounds)
    name, description, dt, substeps = read('name'), read('description'), read('dt'), read('substeps')
    duration = read('duration', lo=dt)
    try:
        duration_steps(duration, dt)
    except ValueError as exc:
        raise ctx.error(E.InvalidValueError, ('duration',), f'duration {exc}') from None
    settle = read('settle_time', hi=duration)
    mismatch = read('model_mismatch')
    return _Timing(name=name, description=description, dt=dt, substeps=substeps, duration=duration,
                   settle_time=settle, model_mismatch=mismatch)


def _helicopter(ctx: ConfigContext, top: dict, base: Path) -> str:
    """Give the helicopter entry: a bundled name as written, a file name resolved against ``base``."""
    helicopter = read_key(ctx, key_named(scenario_keys.SCENARIO_KEYS, 'helicopter'), top)
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


def _faults(ctx: ConfigContext, faults_raw, team: Team) -> dict:
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


def parse_scenario(text: str, *, source: str | None = None, base_dir=None, safety: bool | None = None) -> Scenario:
    """Parse and validate scenario YAML text (``base_dir`` resolves relative file names).

    ``safety`` (True/False) replaces the file's ``safety.enabled`` before validation (the run
    scripts' ``--safety on|off``); None keeps it.
    """
    data, lines = parse_yaml(text, source)
    if data is None:
        raise E.MissingFieldError('the scenario is empty; required keys: '
                                  + ', '.join(key_names(scenario_keys.SCENARIO_KEYS, required=True)),
                                  source=source)
    if safety is not None and isinstance(data, dict):
        given = data.get('safety')
        data['safety'] = {**(given if isinstance(given, dict) else {}), 'enabled': bool(safety)}
    return scenario_from_mapping(data, source=source, base_dir=base_dir, lines=lines)


def bundled_scenarios() -> tuple:
    """Names of the scenarios bundled in ``uh_topology/config`` (e.g. ``('paper',)``)."""
    return tuple(sorted(p.stem for p in CONFIG_DIR.glob('*.yaml')
                        if not p.stem.endswith('_gains') and not p.stem.startswith('campaign_')))


def load_scenario(path_or_name, safety: bool | None = None) -> Scenario:
    """Load and validate a scenario.

    Parameters
    ----------
    path_or_name : str or Path
        A YAML file, or the name of a bundled scenario (``'paper'`` ->
        ``uh_topology/config/paper.yaml``).
    safety : bool, optional
        Replaces the file's ``safety.enabled`` (``--safety on|off``); None keeps the file's.

    Raises
    ------
    ScenarioNotFoundError
        Neither an existing file nor a bundled name.
    ScenarioError
        Any of the specific subclasses of :mod:`uh_topology.errors`.
    """
    if isinstance(path_or_name, Scenario) and (safety is None or path_or_name.safety.enabled == safety):
        return path_or_name
    if isinstance(path_or_name, Scenario):
        raise ValueError('a loaded scenario cannot change its safety setting: load it from its file again')
    path, content = read_config_file(path_or_name, 'scenario', bundled_scenarios)
    return parse_scenario(content, source=str(path), base_dir=path.resolve().parent, safety=safety)
