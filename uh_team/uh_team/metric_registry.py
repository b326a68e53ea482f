"""Every metric of a run, declared once: what it is, how it is computed, and how each reader shows it.

:data:`METRICS` holds one :class:`Metric` per metric, in order. The readers take what they need from
it and nothing else (docs/metrics.md#the-registry-of-metrics):

- ``metrics.json``: the top-level keys (those with a ``json_type``), in this order, each the value
  of its ``compute`` on the checked arrays of the run (:class:`RunValues`); see
  :func:`uh_team.metrics.compute_metrics`;
- ``uh-report``'s metrics table: the metrics with a ``report_row``, sorted by it
  (:func:`report_metrics`);
- a campaign's results file: a REAL column per ``stored`` metric, in this order
  (:func:`stored_metrics`, read from ``metrics.json`` by :meth:`Metric.value`), with its unit in the
  campaign statistics (:func:`campaign_units`);
- ``uh-simulate``'s summary: the ``summary`` metrics (:func:`summary_keys`);
- the tables of docs/metrics.md (:func:`json_table`, :func:`metric_table`).

A new metric is one more :class:`Metric` in :data:`METRICS`, its computation next to it: a new key
goes at the end of ``metrics.json`` and a new column at the end of the results file (a results file
of the old layout is then refused, as after any change of its columns).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cached_property
from typing import Callable

import numpy as np

from uh_controller_node.delay_margin import scenario_margin

from .departures import scenario_departures
from .error_metrics import containment_errors, formation_errors
from .fault_metrics import LUMPED_FAULTS, LumpedFault, false_fault_estimate, fault_estimation, fault_list, none_if_nan
from .hull_geometry import hull_distance
from .isolation_metrics import fault_isolation_metrics
from .reconfiguration import reconfiguration
from .separation_metrics import closest_approach, separation_limits, time_below

__all__ = ['Metric', 'RunValues', 'METRICS', 'BETTER', 'json_metrics', 'json_keys', 'report_metrics',
           'stored_metrics', 'summary_keys', 'campaign_units', 'display_unit', 'json_table', 'metric_table']

#: The words of :attr:`Metric.better`: which way a value is better (``None``: neither).
BETTER = ('lower', 'higher')

_COLUMN_NAME = re.compile(r'[a-z_][a-z0-9_]*')


@dataclass(frozen=True)
class Metric:
    """One metric: the facts every reader of it needs.

    Attributes
    ----------
    name : str
        Its name: the ``metrics.json`` key of a top-level value, else the column of the results
        file (or, if not stored, a name of its own).
    unit : str
        ``m``, ``m^2``, ``m/s^2``, ``s``, ``-`` (a pure number) or ``''`` (not a quantity), as
        docs/metrics.md writes it; :func:`display_unit` gives the tables' form (``m²``).
    description : str
        One line: what the value is (the results file's column, the docs).
    better : str or None
        ``'lower'`` or ``'higher'`` when the value ranks runs (the report marks the best), else ``None``.
    label : str or None
        Text of its row in the report's metrics table.
    report_row : int or None
        Place of its row in the report's metrics table (rows in increasing order); ``None``: no row.
        With no ``label``, a ``metrics.json`` object the report lays out in rows of its own
        (``fault_estimation``: a row per UH and vector).
    json_type : str or None
        Set for a top-level key of ``metrics.json``: the JSON type docs/metrics.md gives it
        (``number or null``, ``object``, ...).
    doc : str
        Content of its row in the ``metrics.json`` table of docs/metrics.md (Markdown).
    compute : callable or None
        ``compute(values: RunValues) -> value`` of a top-level key (JSON-ready: float, str, dict or None).
    path : str or None
        For a number inside a ``metrics.json`` object: its dotted key (``fault_isolation.summary.missed``).
    read : callable or None
        For a number derived from several values of ``metrics.json``: ``read(metrics) -> float or None``.
    stored : bool
        A REAL column (``name``) of a campaign's results file.
    summary : bool
        Printed by ``uh-simulate`` (top-level keys only).
    """

    name: str
    unit: str = ''
    description: str = ''
    better: str | None = None
    label: str | None = None
    report_row: int | None = None
    json_type: str | None = None
    doc: str = ''
    compute: Callable | None = None
    path: str | None = None
    read: Callable | None = None
    stored: bool = False
    summary: bool = False

    def __post_init__(self):
        """Refuse a declaration its readers could not use."""
        problems = []
        if self.better not in (None, *BETTER):
            problems.append(f'better {self.better!r}; allowed: {", ".join(BETTER)} or None')
        if (self.json_type is None) != (self.compute is None):
            problems.append('a top-level key of metrics.json has both json_type and compute, anything else neither')
        if self.json_type is None and (self.path is None) == (self.read is None):
            problems.append('a value inside metrics.json has either a path or a read function')
        if self.json_type is not None and (self.path or self.read):
            problems.append('a top-level key has no path and no read function')
        if self.label is not None and self.report_row is None:
            problems.append('a label needs a report_row')
        if self.report_row is not None and self.key is None:
            problems.append('a report row needs a metrics.json key (json_type or path)')
        if self.summary and self.json_type is None:
            problems.append('uh-simulate summarises top-level keys only')
        if self.stored and not _COLUMN_NAME.fullmatch(self.name):
            problems.append('a stored metric is named like an SQL column ([a-z_][a-z0-9_]*)')
        if problems:
            raise ValueError(f'metric {self.name!r}: ' + '; '.join(problems))

    @property
    def key(self) -> str | None:
        """Its dotted key in ``metrics.json`` (``None`` for a number derived from several values)."""
        return self.name if self.json_type is not None else self.path

    def value(self, metrics: dict):
        """Return its value in a ``metrics.json`` content, ``None`` where the content has none."""
        if self.read is not None:
            return self.read(metrics)
        value = metrics
        for part in self.key.split('.'):
            value = value.get(part) if isinstance(value, dict) else None
        return value


@dataclass
class RunValues:
    """The checked arrays of one run (shapes as :func:`uh_team.metrics.compute_metrics` takes them).

    What several metrics share (errors, windows, the fault estimation) is computed once, on first use.
    ``scenario`` and ``arrays`` are those of :func:`uh_team.metrics.metrics_from_arrays` (``None``
    for :func:`~uh_team.metrics.compute_metrics`, whose ``fault_isolation`` and ``faults`` are then ``None``).
    """

    case: str
    time: np.ndarray
    positions: np.ndarray
    reference_positions: np.ndarray
    leaders: tuple
    followers: tuple
    offsets: np.ndarray
    containment_weights: np.ndarray | None
    z1: np.ndarray
    u_p: np.ndarray
    saturated: np.ndarray
    fault_data: dict
    faulted: dict
    settle_time: float
    wall_time: float | None
    scenario: object = None
    arrays: object = None

    @property
    def ids(self) -> tuple:
        """UH ids in the order of the arrays: leaders, then followers."""
        return self.leaders + self.followers

    @property
    def steps(self) -> int:
        """Number of control steps K (one sample more)."""
        return self.time.shape[0] - 1

    @property
    def dt(self) -> float:
        """Control period, s."""
        return float(self.time[1] - self.time[0])

    @property
    def tolerance(self) -> float:
        """Tolerance of the window limits, s."""
        return 1e-9 * max(self.dt, 1.0)

    @cached_property
    def after(self) -> np.ndarray:
        """Mask of the samples after settle."""
        return self.time >= self.settle_time - self.tolerance

    @property
    def leader_positions(self) -> np.ndarray:
        """Positions of the leaders (K+1, N, 3)."""
        return self.positions[:, :len(self.leaders)]

    @property
    def follower_positions(self) -> np.ndarray:
        """Positions of the followers (K+1, M, 3)."""
        return self.positions[:, len(self.leaders):]

    @cached_property
    def formation(self) -> np.ndarray:
        """Formation errors of the leaders (K+1, N), m."""
        return formation_errors(self.leader_positions, self.reference_positions, self.offsets)

    @cached_property
    def containment(self) -> np.ndarray | None:
        """Containment errors of the followers (K+1, M), m; ``None`` without followers."""
        if not self.followers:
            return None
        return containment_errors(self.follower_positions, self.leader_positions, self.containment_weights)

    @cached_property
    def estimation(self) -> dict:
        """The ``fault_estimation`` section (docs/metrics.md#fault-estimation-error-and-nrmse)."""
        return fault_estimation(self.time[:self.steps], self.ids, self.faulted, self.fault_data, self.tolerance)


# ----------------------------------------------------------------------------------------------
# Computations (docs/metrics.md); a step a real-time run did not record (NaN) contributes nothing
# ----------------------------------------------------------------------------------------------
def _after_settle_rms(errors, values: RunValues):
    if errors is None or not values.after.any():
        return None
    selected = errors[values.after]
    if not np.isfinite(selected).any():     # nothing recorded after settling (e.g. a UH's simulator died)
        return None
    return none_if_nan(np.sqrt(np.nanmean(selected ** 2)))


def _hull_distance_max(v: RunValues):
    if not v.followers or not v.after.any():
        return None
    hull = hull_distance(v.follower_positions[v.after], v.leader_positions[v.after][:, None, :, :])
    return none_if_nan(np.nanmax(hull)) if np.isfinite(hull).any() else None


def _cpi(v: RunValues):
    # a missing step makes the CPI slightly lower; lockstep and in-process runs have every step
    return none_if_nan(v.dt * (np.nansum(v.z1 * v.z1) + np.nansum(v.u_p * v.u_p)))


def _separation(v: RunValues) -> dict:
    limits = separation_limits(v.scenario)
    closest = closest_approach(v.time, v.positions, v.ids)
    warnings = [] if v.scenario is None else [issue.text() for issue in v.scenario.separation_warnings]
    return {'limit_m': limits['min_separation_m'], 'rotor_overlap_m': limits['rotor_overlap_m'],
            'closest_time_s': closest['time_s'], 'design_warnings': warnings}


def _safety_active_s(v: RunValues):
    """Seconds during which the safety filter of at least one UH changed its ``u_p`` (steps 0..K-1)."""
    active = None if v.arrays is None else v.arrays.get('safety_active')
    if active is None:
        return None
    return float(np.count_nonzero(np.asarray(active)[:v.steps].any(axis=1)) * v.dt)


def _time_below(v: RunValues, limit: str):
    return time_below(v.time, v.positions, separation_limits(v.scenario)[limit])


def _false_fault_estimate(v: RunValues) -> dict:
    return false_fault_estimate(v.time[:v.steps], v.ids, v.faulted, v.fault_data, v.tolerance)


def _fault_nrmse(v: RunValues) -> dict:
    return {uh: {f.symbol: entry[f.key]['nrmse'] for f in LUMPED_FAULTS if f.key in entry}
            for uh, entry in v.estimation.items()}


def _fault_isolation(v: RunValues):
    return None if v.scenario is None else fault_isolation_metrics(v.arrays, v.scenario, v.case)


def _faults(v: RunValues):
    return None if v.scenario is None else fault_list(v.scenario, v.arrays)


def _false_fault_max(fault: LumpedFault, report_row: int) -> Metric:
    """Declare the largest false fault estimate of one lumped-fault vector over the UHs."""
    hat = fault.symbol.replace('F', 'F̂')
    return Metric(f'false_fault_{fault.key}', fault.unit,
                  f'largest RMS |Fhat_{fault.key}| where no fault acts, {fault.unit}', 'lower',
                  label=f'false fault estimate RMS ‖{hat}‖, max over UHs '
                        f'(threshold {fault.false_estimate_threshold:g})',
                  report_row=report_row, path=f'false_fault_estimate.max.{fault.key}', stored=True)


def _fault_error_max(fault: LumpedFault) -> Metric:
    """Declare the largest fault estimation error of one lumped-fault vector over the faulted UHs."""
    def read(metrics: dict):
        errors = [entry[fault.key]['rms_error'] for entry in (metrics.get('fault_estimation') or {}).values()
                  if fault.key in entry and entry[fault.key].get('rms_error') is not None]
        return max(errors) if errors else None
    return Metric(f'fault_error_{fault.key}', fault.unit,
                  f'largest RMS |Fhat_{fault.key} - F_{fault.key}| over the faulted UHs, {fault.unit}', 'lower',
                  read=read, stored=True)


def _slowest_mode(values) -> float | None:
    """Give the time constant of the team's slowest linear mode (:mod:`uh_controller_node.delay_margin`), s."""
    if values.scenario is None:
        return None
    return float(scenario_margin(values.scenario, values.case, most=0, compensations=()).slowest_mode.time_constant_s)


def _departures(values) -> dict:
    """Give the run's departures from the paper (:func:`~uh_team.departures.scenario_departures`), {} without one."""
    return {} if values.scenario is None else scenario_departures(values.scenario, values.case)


def _over_losses(metrics: dict, value, pick=max):
    """Give ``pick`` of ``value(event)`` over the run's ``reconfiguration`` entries.

    None without events, or when ``value`` has nothing for one of them (a loss never re-formed counts
    as no time at all, not as the others' largest).
    """
    events = metrics.get('reconfiguration')
    if not events:
        return None
    values = [value(event) for event in events]
    return None if any(v is None for v in values) else pick(values)


def _since_loss(key: str):
    """Give the reader of the time from a loss to its event's ``key`` (``agreed_at_s``, ``reformed_at_s``), s."""
    return lambda event: None if event.get(key) is None else round(event[key] - event['time_s'], 9)


def _loss_metric(name: str, unit: str, description: str, better: str, value, pick=max) -> Metric:
    """Declare a campaign column of a run's losses: ``pick`` of ``value(event)`` over its events."""
    return Metric(name, unit, description, better, read=lambda metrics: _over_losses(metrics, value, pick),
                  stored=True)


_P, _W = LUMPED_FAULTS

#: Every metric, in the order of ``metrics.json``'s keys and of the results file's columns.
METRICS = (
    Metric('case', '', 'controller case', label='controller case', report_row=10, json_type='string',
           doc='controller case: `proposed`, `case1`, `case2`', compute=lambda v: str(v.case)),
    Metric('departures', json_type='object',
           doc="departures from the paper's graph and gains the run made (the delay remedies of "
               '[delay.md](delay.md#remedies)): `reference_links`, `delay_compensation`, `feedforward_weight`; '
               'with events `on_loss: reform` ([resilience.md](resilience.md)); `{}`: none',
           compute=lambda v: _departures(v)),
    Metric('sim_time_s', 's', 'simulated time span', label='simulated time', report_row=20, json_type='number',
           doc='simulated time span `t_K - t_0`, s', compute=lambda v: float(v.time[-1] - v.time[0])),
    Metric('wall_time_s', 's', 'wall-clock duration of the run', label='wall time of the run', report_row=170,
           json_type='number or null', doc="wall-clock duration of the run, s (the run script's or the simulation's)",
           compute=lambda v: None if v.wall_time is None else float(v.wall_time)),
    Metric('settle_time_s', 's', 'start of the after-settle window', label='settle time', report_row=160,
           json_type='number', doc='start of the after-settle window, s', compute=lambda v: float(v.settle_time)),
    Metric('formation_rms_m', 'm', 'RMS formation error of the leaders after settle, m', 'lower',
           label='formation RMS after settle', report_row=60, json_type='number or null',
           doc='[after settle](#after-settle-window), m', compute=lambda v: _after_settle_rms(v.formation, v),
           stored=True, summary=True),
    Metric('containment_rms_m', 'm', 'RMS containment error of the followers after settle, m', 'lower',
           label='containment RMS after settle', report_row=70, json_type='number or null', doc='after settle, m',
           compute=lambda v: _after_settle_rms(v.containment, v), stored=True, summary=True),
    Metric('hull_distance_max_m', 'm', "largest follower distance to the leaders' convex hull after settle, m",
           'lower', label='max distance outside the hull after settle', report_row=80, json_type='number or null',
           doc='after settle, m', compute=_hull_distance_max, stored=True, summary=True),
    Metric('mse_formation', 'm^2', 'mean squared formation error from t = 0, m^2', 'lower',
           label='MSE formation (whole run)', report_row=40, json_type='number or null',
           doc='[whole run](#mean-squared-errors), m^2', compute=lambda v: none_if_nan(np.nanmean(v.formation ** 2)),
           stored=True, summary=True),
    Metric('mse_containment', 'm^2', 'mean squared containment error from t = 0, m^2', 'lower',
           label='MSE containment (whole run)', report_row=50, json_type='number or null', doc='whole run, m^2',
           compute=lambda v: None if v.containment is None else none_if_nan(np.nanmean(v.containment ** 2)),
           stored=True, summary=True),
    Metric('cpi', '-', 'cost performance index, integral of |z1|^2 + |u_p|^2', 'lower',
           label='CPI = ∫ Σ (‖z1‖² + ‖u_p‖²) dt', report_row=30, json_type='number or null', doc='[CPI](#cpi)',
           compute=_cpi, stored=True, summary=True),
    Metric('slowest_mode_s', 's', "time constant of the team's slowest linear mode without delay, s", 'lower',
           json_type='number or null',
           doc="[the linearised team's](delay.md#delay-margin) slowest mode without delay, its time constant, s; "
               'null without a scenario',
           compute=lambda v: _slowest_mode(v), stored=True),
    Metric('fault_estimation', report_row=120, json_type='object',
           doc='[per faulted UH and vector](#fault-estimation-error-and-nrmse), below',
           compute=lambda v: v.estimation),
    Metric('false_fault_estimate', json_type='object',
           doc='[per UH with a window, and the maximum](#false-fault-estimate), below', compute=_false_fault_estimate),
    Metric('fault_nrmse', json_type='object',
           doc='the `nrmse` values of `fault_estimation` in the layout of earlier versions: '
               '`{"uh<i>": {"F_p": ..., "F_w": ...}}` (`null` below the floor)', compute=_fault_nrmse),
    Metric('saturation_fraction', '-', 'fraction of (step, UH) samples with an input limit active', 'lower',
           label='saturated fraction of steps', report_row=90, json_type='number',
           doc='[fraction of saturated steps](#saturation-fraction)',
           compute=lambda v: float(np.mean(v.saturated)) if v.saturated.size else 0.0, stored=True, summary=True),
    _false_fault_max(_P, report_row=100),
    _false_fault_max(_W, report_row=110),
    _fault_error_max(_P),
    _fault_error_max(_W),
    Metric('fault_isolation', json_type='object or null',
           doc='[per UH with a faulted or isolated channel, and a summary](#fault-isolation), below',
           compute=_fault_isolation),
    Metric('false_isolations', '-', 'channels isolated by a controller that carry no fault', 'lower',
           label='false isolations (isolated channels not faulty)', report_row=130,
           path='fault_isolation.summary.false_isolations', stored=True),
    Metric('missed_isolations', '-', 'faulted channels no controller isolated', 'lower',
           label='faulted channels never isolated', report_row=140, path='fault_isolation.summary.missed',
           stored=True),
    Metric('max_isolation_delay', 's', 'largest delay from a fault onset to its isolation', 'lower',
           label='largest isolation delay after the onset', report_row=150, path='fault_isolation.summary.max_delay'),
    Metric('faults', json_type='object or null', compute=_faults,
           doc="the run's faults: `scheduled` (the scenario's: `uh`, `channel`, `rho`, `bias_constant`, "
               '`bias_amplitude`, `bias_frequency`, `onset_time`) and `injected` (those the simulators applied, '
               'the same fields with `onset_time` when it acts, `sent_onset_time`, `received_s`, `nominal`: '
               'an injection that clears its channel, not scored, and `stuck_in_place`: stuck where it was on '
               'arrival, `rho` 0, its position not known)'),
    Metric('min_separation_m', 'm', 'smallest hub-to-hub distance of any two UHs over the run, m', 'higher',
           label='closest approach of two UHs (hub to hub)', report_row=82, json_type='number or null',
           doc='[smallest distance of any two UHs, whole run](#separation), m',
           compute=lambda v: closest_approach(v.time, v.positions, v.ids)['distance_m'], stored=True, summary=True),
    Metric('min_separation_pair', json_type='string or null', doc='the pair of that approach, `UH4-UH5`',
           compute=lambda v: closest_approach(v.time, v.positions, v.ids)['pair']),
    Metric('separation_violation_s', 's', 'time some pair is closer than the minimum separation, s', 'lower',
           label='time under the minimum separation', report_row=84, json_type='number or null',
           doc="time some pair is closer than the scenario's `safety.min_separation`, s",
           compute=lambda v: _time_below(v, 'min_separation_m'), stored=True, summary=True),
    Metric('rotor_overlap_s', 's', 'time some pair is closer than two rotor radii (rotor disks overlap), s', 'lower',
           label='time with rotor disks overlapping', report_row=86, json_type='number or null',
           doc='time some pair is closer than two rotor radii of the airframe (their rotor disks overlap), s',
           compute=lambda v: _time_below(v, 'rotor_overlap_m'), stored=True, summary=True),
    Metric('safety_active_s', 's', 'time the safety filter of some UH changed its u_p, s', 'lower',
           label='time the safety filter acted', report_row=88, json_type='number or null',
           doc='time during which the [safety filter](safety.md) of at least one UH changed its `u_p`, s '
               '(0 with the filter off)', compute=_safety_active_s, stored=True, summary=True),
    Metric('separation', json_type='object',
           doc='`limit_m` (the minimum separation), `rotor_overlap_m` (two rotor radii), `closest_time_s` and '
               "`design_warnings` (the scenario's formation targets or initial positions closer than the limit)",
           compute=_separation),
    # docs/resilience.md: a run with events
    Metric('reconfiguration', json_type='array or null',
           doc='per loss (the scenario\'s `events`; in a recorded run the losses its states carried, '
               '[resilience.md](resilience.md)): `uh`, `kind` (`lost`; `stuck` for a UH that left after that '
               'event, `unable` without one), `time_s` (the event), `channel` (the one its isolator found, for a '
               'UH that left), `on_loss`, '
               '`detected_at_s` (the first declaration), `agreed_at_s` (every UH knows), `reformed_at_s` (errors '
               'under 0.05 m / 0.02 m against the new targets from then on), `formation_error_after_m` and '
               '`containment_error_after_m` (largest after re-forming), `formation_error_last_10s_m` and '
               '`containment_error_last_10s_m` (largest over the last 10 s before the next event or the end), '
               '`min_separation_m` (from the event to re-forming), the new `leaders`, `followers`, `promoted` '
               '(slot: UH) and `holding` (UH: why); null without a loss',
           compute=lambda v: None if v.scenario is None else reconfiguration(
               v.time, v.positions, v.reference_positions, v.scenario, (v.arrays or {}).get('losses'),
               (v.arrays or {}).get('leaving'))),
    # ... and its campaign columns (docs/campaigns.md#losing-a-helicopter): over the run's losses, none without
    _loss_metric('reform_time_s', 's', 'largest time from a loss to the team re-formed, s (none if one was not)',
                 'lower', _since_loss('reformed_at_s')),
    _loss_metric('agree_time_s', 's', 'largest time from a loss to every surviving UH knowing of it, s (none if one '
                 'was not)', 'lower', _since_loss('agreed_at_s')),
    _loss_metric('loss_formation_last_10s_m', 'm',
                 "largest leader error over a loss's last 10 s, against the team then in force, m", 'lower',
                 lambda event: event.get('formation_error_last_10s_m')),
    _loss_metric('loss_containment_last_10s_m', 'm',
                 "largest follower error over a loss's last 10 s, against the team then in force, m", 'lower',
                 lambda event: event.get('containment_error_last_10s_m')),
    _loss_metric('loss_min_separation_m', 'm', 'smallest hub-to-hub distance from a loss to re-forming (or the '
                 'end), m', 'higher', lambda event: event.get('min_separation_m'), pick=min),
)


# ----------------------------------------------------------------------------------------------
# What each reader takes
# ----------------------------------------------------------------------------------------------
def json_metrics() -> tuple:
    """Return the top-level metrics of ``metrics.json``, in order."""
    return tuple(m for m in METRICS if m.json_type is not None)


def json_keys() -> tuple:
    """Return the keys of ``metrics.json``, in order."""
    return tuple(m.name for m in json_metrics())


def report_metrics() -> tuple:
    """Return the metrics the report's metrics table shows, in the order of its rows."""
    return tuple(sorted((m for m in METRICS if m.report_row is not None), key=lambda m: m.report_row))


def stored_metrics() -> tuple:
    """Return the metrics stored as columns of a campaign's results file, in order."""
    return tuple(m for m in METRICS if m.stored)


def summary_keys() -> tuple:
    """Return the ``metrics.json`` keys ``uh-simulate`` prints, in order."""
    return tuple(m.name for m in METRICS if m.summary)


def display_unit(unit: str) -> str:
    """Return a unit as the tables write it (``m^2`` as ``m²``)."""
    return unit.replace('^2', '²')


def campaign_units() -> dict:
    """``{column: unit}`` of the metric columns of a campaign's results file, as the tables write them."""
    return {m.name: display_unit(m.unit) for m in stored_metrics()}


def _markdown(head, rows) -> str:
    cell = lambda text: text.replace('|', '\\|')  # noqa: E731
    lines = ['| ' + ' | '.join(head) + ' |', '|' + '---|' * len(head)]
    lines += ['| ' + ' | '.join(cell(c) for c in row) + ' |' for row in rows]
    return '\n'.join(lines)


def json_table() -> str:
    """Return the Markdown table of the keys of ``metrics.json`` (docs/metrics.md#metricsjson)."""
    return _markdown(('key', 'type', 'content'), [(f'`{m.name}`', m.json_type, m.doc) for m in json_metrics()])


def metric_table() -> str:
    """Return the Markdown table of the metrics shown in tables (docs/metrics.md#the-registry-of-metrics)."""
    rows = []
    for m in METRICS:
        readers = [*(['report'] if m.label else []), *(['campaign'] if m.stored else []),
                   *(['uh-simulate'] if m.summary else [])]
        if readers:
            rows.append((f'`{m.name}`', f'`{m.key}`' if m.key else '-', m.unit, m.better or '-',
                         ', '.join(readers), m.description))
    return _markdown(('metric', 'metrics.json key', 'unit', 'better', 'shown by', 'description'), rows)
