"""The fault isolator over a whole recorded run: one :class:`~uh_controller_node.fault_isolation.FaultIsolator` per UH.

What a controller does step by step (:mod:`uh_controller_node.fault_isolation`), replayed over a
team run's time series (``timeseries.npz`` or a bag read back): :func:`isolate_run` gives every
UH's verdicts as the controllers would have published them (docs/faults.md#isolation-and-identification);
:func:`healthy_deviation_statistics` the deviations of healthy channels, from which the thresholds
were chosen; :func:`first_unable` when each UH's isolator finds a fault its controller cannot compensate.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from uh_core.airframe import load_helicopter_params

from .fault_isolation import CHANNELS, FaultIsolator, IsolationSettings
from .gains import ControllerGains
from .nominal_model import nominal_model

__all__ = ['isolate_run', 'first_unable', 'healthy_deviation_statistics']

_N = len(CHANNELS)


def _setup(arrays, scenario, case, settings):
    """Return the nominal model, the settings and the run's arrays.

    The settings default to the scenario's learning phase; the arrays are float arrays, rows cut to
    the shortest.
    """
    if settings is None:
        phase = ControllerGains.from_mapping(scenario.gains, case).learning_phase
        settings = IsolationSettings(learning_phase=float(phase))
    nominal = nominal_model(load_helicopter_params(scenario.helicopter), scenario.model_mismatch)
    keys = ('time', 'states', 'commands', 'fault_est_p', 'fault_est_w')
    data = {key: np.asarray(arrays[key], dtype=float) for key in keys}
    rows = min(len(v) for v in data.values())
    n = len(tuple(scenario.ids))
    if data['states'].ndim != 3 or data['states'].shape[1] != n:
        raise ValueError(f'arrays have UH axis {data["states"].shape[1:2]}, the scenario {n} UHs')
    return nominal, settings, {key: v[:rows] for key, v in data.items()}


def _steps(data, j):
    """Per-step arguments of :meth:`FaultIsolator.update` for UH column ``j``."""
    return zip(data['time'].tolist(), data['states'][:, j].tolist(), data['commands'][:, j].tolist(),
               data['fault_est_p'][:, j].tolist(), data['fault_est_w'][:, j].tolist(), strict=False)


def isolate_run(arrays, scenario, case: str = 'proposed', settings: IsolationSettings | None = None) -> dict:
    """Run one :class:`FaultIsolator` per UH over a team run's time series.

    Parameters
    ----------
    arrays : mapping
        ``time`` (K+1,) s, ``states`` (K+1, n, 12), ``commands`` (K or K+1, n, 4) rad,
        ``fault_est_p`` m/s^2, ``fault_est_w`` rad/s^2 (K or K+1, n, 3); UH axis in
        ``scenario.ids`` order; the estimates of row ``k`` are those the controller used at step
        ``k`` (``uh_team.team_simulation.TeamRun.arrays()``, or a recorded run's arrays). Rows
        beyond the shortest array are ignored.
    scenario : uh_topology.scenario.Scenario
        Gives the helicopter, the model mismatch, ``dt`` and (with ``case``) the learning phase.
    case : str
        Controller case whose gains give the learning phase.
    settings : IsolationSettings, optional
        Default: :class:`IsolationSettings` with the scenario's learning phase.

    Returns
    -------
    dict
        ``{"uh<i>": {"isolated": [channel names], "channels": {name: ChannelReport.as_dict()}}}``
        for every UH, and ``"settings"``: the settings used, as a dict. Deterministic.
    """
    nominal, settings, data = _setup(arrays, scenario, case, settings)
    out = {}
    for j, uh in enumerate(tuple(scenario.ids)):
        iso = FaultIsolator(nominal, scenario.model_mismatch, float(scenario.dt), settings)
        iso.run(data['time'], data['states'][:, j], data['commands'][:, j], data['fault_est_p'][:, j],
                data['fault_est_w'][:, j])
        reports = iso.report()
        out[f'uh{uh}'] = {
            'isolated': [r.channel for r in reports if r.isolated],
            'channels': {r.channel: r.as_dict() for r in reports},
        }
    out['settings'] = dataclasses.asdict(settings)
    return out


def first_unable(arrays, scenario, case: str, floor: float, spread: float, uhs) -> dict:
    """Give ``{uh: (step, channel)}``: the first step each of ``uhs``' isolators finds a channel below ``floor``.

    The isolator of each UH runs over the run's rows (``arrays`` as for :func:`isolate_run`) until
    :meth:`FaultIsolator.unable` finds a channel (``floor``, ``spread`` rad;
    docs/resilience.md#leaving-the-team); a UH without a finding is left out. The same kernels as the
    controllers' online isolators, so the same steps.
    """
    nominal, settings, data = _setup(arrays, scenario, case, None)
    ids = tuple(scenario.ids)
    out = {}
    for uh in uhs:
        j = ids.index(uh)
        iso = FaultIsolator(nominal, scenario.model_mismatch, float(scenario.dt), settings)
        k, c = iso.first_unable(floor, spread, data['time'], data['states'][:, j], data['commands'][:, j],
                                data['fault_est_p'][:, j], data['fault_est_w'][:, j])
        if k >= 0:
            out[uh] = (k, c)
    return out


def healthy_deviation_statistics(arrays, scenario, case: str = 'proposed',
                                 settings: IsolationSettings | None = None,
                                 settle: float = 1.0) -> dict:
    """Return the healthy deviation statistics the default thresholds and noise levels are set from.

    See docs/faults.md#isolation-and-identification. Per channel, over every fault-free UH and over
    every faulted UH before its earliest onset, after the learning phase.

    Parameters
    ----------
    arrays, scenario, case, settings
        As for :func:`isolate_run` (the scenario's faults say which samples are healthy).
    settle : float
        s after the learning phase from which ``rms`` is taken (the networks' switch-over
        transient at the end of the phase is left out of it).

    Returns
    -------
    dict
        ``{channel name: {"filtered_max": rad, "filtered_max_at": "uh<i> t=<s>", "rms": rad}}``:
        the largest ``|filtered d|`` after the learning phase and the largest per-UH RMS of the
        raw ``d`` after ``learning_phase + settle``.
    """
    nominal, settings, data = _setup(arrays, scenario, case, settings)
    out = {name: {'filtered_max': 0.0, 'filtered_max_at': None, 'rms': 0.0} for name in CHANNELS}
    for j, uh in enumerate(tuple(scenario.ids)):
        onset = min((float(f.onset_time) for f in scenario.faults[uh]), default=math.inf)
        iso = FaultIsolator(nominal, scenario.model_mismatch, float(scenario.dt), settings)
        sums, counts = [0.0] * _N, 0
        for step in _steps(data, j):
            t = step[0]
            if t >= onset - 1e-9:
                break
            iso.update(*step)
            if t < settings.learning_phase - 1e-9:
                continue
            y, d = iso.filtered_deviation, iso.deviation
            for c, name in enumerate(CHANNELS):
                if abs(y[c]) > out[name]['filtered_max']:
                    out[name]['filtered_max'] = abs(y[c])
                    out[name]['filtered_max_at'] = f'uh{uh} t={t:.2f}'
            if t >= settings.learning_phase + settle - 1e-9:
                counts += 1
                for c in range(_N):
                    sums[c] += d[c] * d[c]
        if counts:
            for c, name in enumerate(CHANNELS):
                out[name]['rms'] = max(out[name]['rms'], math.sqrt(sums[c] / counts))
    return out
