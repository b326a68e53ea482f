"""Scoring of the fault isolation of a run against its scenario's faults (docs/metrics.md#fault-isolation).

The verdicts are those of the causal isolator every controller runs
(:mod:`uh_controller_node.fault_isolation`): as published on each controller's last status (a
recorded run) or recomputed over the run's arrays (an in-process run).
"""
from __future__ import annotations

import math

import numpy as np

from uh_controller_node.fault_isolation import IDENTIFIABLE, IDENTIFICATION_TEXT
from uh_controller_node.isolation_runs import isolate_run
from uh_core.layout import CHANNEL_NAMES

from .fault_metrics import fault_spec_value, run_faults

__all__ = ['ISOLATION_ARRAYS', 'fault_isolation_metrics']

#: Arrays the fault isolation needs (``uh_controller_node.isolation_runs.isolate_run``).
ISOLATION_ARRAYS = ('time', 'states', 'commands', 'fault_est_p', 'fault_est_w')


def _channel_faults(scenario, end: float, arrays=None) -> dict:
    """Return ``{uh id: {channel: (onset, rho, bias_constant)}}`` of the run's faults (scheduled and injected).

    Only those whose onset is at or before ``end`` (s); the earliest fault of a channel counts.
    """
    out = {}
    for uh, specs in sorted(run_faults(scenario, arrays).items()):
        for spec in specs:
            onset, channel = float(fault_spec_value(spec, 'onset_time')), int(fault_spec_value(spec, 'channel'))
            if onset > end:
                continue
            known = out.setdefault(int(uh), {}).get(channel)
            if known is None or onset < known[0]:
                out[int(uh)][channel] = (onset, float(fault_spec_value(spec, 'rho')),
                                          float(fault_spec_value(spec, 'bias_constant')))
    return {uh: chans for uh, chans in out.items() if chans}


def fault_isolation_metrics(arrays, scenario, case: str) -> dict | None:
    """``fault_isolation`` of docs/metrics.md.

    The verdicts of the isolator every controller runs step by step (docs/faults.md#isolation-and-identification),
    scored against the scenario's faults. The verdicts are those the controllers published when ``arrays`` has an
    ``isolation`` entry for every UH (``uh_report.bag_metrics.read_team_bag``), else
    ``uh_controller_node.isolation_runs.isolate_run`` over the arrays (the same computation).

    Parameters
    ----------
    arrays : mapping
        :data:`ISOLATION_ARRAYS` in the layout of :func:`metrics_from_arrays`. Rows where any of
        them is not finite for any UH (a step a real-time run did not record) are left out.
    scenario : uh_topology.scenario.Scenario
    case : str
        Controller case (its gains give the learning phase).

    Returns
    -------
    dict or None
        ``{"uh<i>": {channel name: entry}}`` for every UH with a faulted or an isolated channel,
        entries with ``faulty``, ``onset`` (s or ``None``), ``isolated``, ``detected_at`` (s),
        ``delay`` (s after the onset; ``None`` unless faulty and isolated), ``rho``, ``bias`` (rad;
        ``None`` unless ``identifiable``), ``identifiable``, ``reason``, ``rho_true``,
        ``bias_constant_true`` (rad; 1 and 0 on a healthy channel); and ``"summary"``:
        ``false_isolations`` (isolated channels that are not faulty, healthy UHs included),
        ``missed`` (faulty channels never isolated), ``max_delay`` (s, ``None`` without an
        isolated faulty channel), ``source`` (``"status"`` or ``"recomputed"``). ``reason`` is the
        verdict's text (``IDENTIFICATION_TEXT``). ``None`` if an array is missing or does not fit
        the scenario. A fault counts as faulty from its onset, if that is within the run.
    """
    if any(key not in arrays for key in ISOLATION_ARRAYS):
        return None
    n = len(tuple(scenario.ids))
    data = {key: np.asarray(arrays[key], dtype=float) for key in ISOLATION_ARRAYS}
    rows = min(v.shape[0] for v in data.values())
    if rows < 2 or any(v.ndim < 2 or v.shape[1] != n for k, v in data.items() if k != 'time'):
        return None
    data = {key: v[:rows] for key, v in data.items()}
    keep = np.isfinite(data['time'])
    for key, v in data.items():
        if key != 'time':
            keep &= np.isfinite(v.reshape(rows, -1)).all(axis=1)
    if keep.sum() < 2:
        return None
    data = {key: v[keep] for key, v in data.items()}
    published = arrays.get('isolation') or {}
    if all(int(uh) in published for uh in scenario.ids):
        # what each controller published on its last status (a recorded run)
        source = 'status'
        verdicts = {int(uh): _published_verdicts(published[int(uh)], CHANNEL_NAMES) for uh in scenario.ids}
    else:
        # the same isolator, recomputed over the arrays (an in-process run)
        source = 'recomputed'
        isolation = isolate_run(data, scenario, case)
        verdicts = {}
        for uh in tuple(scenario.ids):
            verdicts[int(uh)] = {
                name: {'isolated': bool(r['isolated']), 'detection_time': r['detection_time'],
                       'rho': r['rho'], 'bias': r['bias'], 'identifiable': bool(r['identifiable']),
                       'reason': IDENTIFICATION_TEXT[r['identification']]}
                for name, r in isolation[f'uh{uh}']['channels'].items()}
    end = float(data['time'][-1]) + 1e-9 * max(float(scenario.dt), 1.0)
    truth = _channel_faults(scenario, end, arrays)
    out, false_isolations, missed, delays = {}, 0, 0, []
    for uh in tuple(scenario.ids):
        reports = verdicts[int(uh)]
        faults = truth.get(int(uh), {})
        if not faults and not any(r['isolated'] for r in reports.values()):
            continue
        entry = {}
        for c, name in enumerate(CHANNEL_NAMES):
            r = reports[name]
            onset, rho_true, bias_true = faults.get(c, (None, 1.0, 0.0))
            faulty = onset is not None
            delay = round(r['detection_time'] - onset, 9) if faulty and r['isolated'] else None
            false_isolations += int(r['isolated'] and not faulty)
            missed += int(faulty and not r['isolated'])
            if delay is not None:
                delays.append(delay)
            entry[name] = {'faulty': faulty, 'onset': onset, 'isolated': bool(r['isolated']),
                           'detected_at': r['detection_time'], 'delay': delay, 'rho': r['rho'],
                           'bias': r['bias'], 'identifiable': bool(r['identifiable']),
                           'reason': r['reason'], 'rho_true': rho_true, 'bias_constant_true': bias_true}
        out[f'uh{uh}'] = entry
    out['summary'] = {'false_isolations': false_isolations, 'missed': missed,
                      'max_delay': max(delays) if delays else None, 'source': source}
    return out


def _published_verdicts(published: dict, names) -> dict:
    """Return the verdict entries of :func:`fault_isolation_metrics` from a published status, per channel name.

    From the fault isolation fields of a controller's last ``ControllerStatus``
    (``uh_report.bag_metrics.read_team_bag``'s ``isolation``).
    """
    def finite(value):
        return float(value) if math.isfinite(value) else None

    out = {}
    for c, name in enumerate(names):
        ok = published['identification'][c] == IDENTIFIABLE
        out[name] = {'isolated': bool(published['isolated'][c]),
                     'detection_time': finite(published['detection_time'][c]),
                     'rho': finite(published['effectiveness'][c]) if ok else None,
                     'bias': finite(published['bias'][c]) if ok else None,
                     'identifiable': ok,
                     'reason': IDENTIFICATION_TEXT.get(published['identification'][c], 'unknown verdict')}
    return out
