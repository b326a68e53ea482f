"""Scoring of the fault estimates of a run.

Which UHs and vectors are scored, over which steps, and how (docs/metrics.md#fault-estimation,
docs/metrics.md#false-fault-estimate).

The lumped faults ``F_p`` (position loop, m/s^2) and ``F_w`` (attitude loop, rad/s^2) are arrays
(K, n, 3) per step and UH; :func:`fault_estimation` scores the estimate of each faulted UH after
its onset, :func:`false_fault_estimate` the estimate where no fault acts.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from uh_sim_node.faults import ActuatorFault, FaultError

from .hull_geometry import dot

__all__ = ['MetricsError', 'FaultedUH', 'LumpedFault', 'LUMPED_FAULTS', 'FAULT_WINDOW_DELAY',
           'FALSE_ESTIMATE_START', 'FALSE_ESTIMATE_THRESHOLD_P', 'FALSE_ESTIMATE_THRESHOLD_W',
           'NRMSE_TARGET', 'NRMSE_FLOOR_P', 'NRMSE_FLOOR_W', 'NOT_MEANINGFUL_MARK', 'fault_spec_value',
           'faulted_uhs', 'injected_faults', 'run_faults', 'fault_list', 'none_if_nan', 'rms_norm',
           'nrmse_below_floor', 'fault_estimation',
           'false_fault_estimate']

#: Delay after a UH's fault onset before its fault estimate is scored, s (docs/metrics.md).
FAULT_WINDOW_DELAY = 5.0

#: Start-up left out of the false fault estimate, s: the observers start at zero and their first
#: seconds hold transients unrelated to any fault (docs/metrics.md#false-fault-estimate).
FALSE_ESTIMATE_START = 5.0

#: Acceptance threshold of the false fault estimate of ``Fhat_p`` (maximum over the UHs), m/s^2;
#: also the estimator's resolution on a healthy UH, from which :data:`NRMSE_FLOOR_P` follows.
FALSE_ESTIMATE_THRESHOLD_P = 0.05

#: Acceptance threshold of the false fault estimate of ``Fhat_w`` (maximum over the UHs), rad/s^2;
#: also the estimator's resolution on a healthy UH, from which :data:`NRMSE_FLOOR_W` follows.
FALSE_ESTIMATE_THRESHOLD_W = 0.1

#: Fault NRMSE the estimator is asked to reach (-).
NRMSE_TARGET = 0.25

#: Smallest RMS of the true ``F_p`` for which the NRMSE is reported, m/s^2: resolution / target.
#: Below it the ratio measures the smallness of the truth, not the estimator (docs/metrics.md).
NRMSE_FLOOR_P = FALSE_ESTIMATE_THRESHOLD_P / NRMSE_TARGET      # 0.2

#: Smallest RMS of the true ``F_w`` for which the NRMSE is reported, rad/s^2: resolution / target.
NRMSE_FLOOR_W = FALSE_ESTIMATE_THRESHOLD_W / NRMSE_TARGET      # 0.4

#: What tables and console output show instead of an NRMSE withheld below the floor.
NOT_MEANINGFUL_MARK = 'n/m'


class MetricsError(ValueError):
    """Arrays of inconsistent shape or missing data handed to the metrics."""


@dataclass(frozen=True)
class FaultedUH:
    """Which lumped faults of one UH are scored (docs/metrics.md).

    Attributes
    ----------
    onset : float
        Earliest fault onset of the UH, s.
    collective : bool
        The collective (channel 0) is faulted, so ``F_p`` is scored too.
    """

    onset: float
    collective: bool

    def scored_vectors(self) -> tuple:
        """Return the :data:`LUMPED_FAULTS` scored for this UH.

        ``F_p`` only with a collective fault (only the collective acts on the position loop), ``F_w`` always (every
        channel moves the rotor moments).
        """
        return tuple(v for v in LUMPED_FAULTS if v.key == 'w' or self.collective)


@dataclass(frozen=True)
class LumpedFault:
    """One lumped-fault vector as the metrics, the report and the CLI name it.

    Attributes
    ----------
    key : str
        Key in ``metrics.json`` (``'p'`` or ``'w'``).
    symbol : str
        ``'F_p'`` or ``'F_w'`` (the key of the ``fault_nrmse`` layout).
    loop : str
        ``'position'`` or ``'attitude'``.
    unit : str
        ``'m/s^2'`` or ``'rad/s^2'``.
    true_array, estimate_array : str
        Keys of the true and estimated vectors in a run's arrays (``fault_true_p``, ``fault_est_p``).
    false_estimate_threshold : float
        Acceptance threshold of the false fault estimate, ``unit``.
    nrmse_floor : float
        Smallest true RMS for which the NRMSE is reported, ``unit``.
    """

    key: str
    symbol: str
    loop: str
    unit: str
    true_array: str
    estimate_array: str
    false_estimate_threshold: float
    nrmse_floor: float


#: The two lumped-fault vectors, position loop first.
LUMPED_FAULTS = (
    LumpedFault('p', 'F_p', 'position', 'm/s^2', 'fault_true_p', 'fault_est_p',
                FALSE_ESTIMATE_THRESHOLD_P, NRMSE_FLOOR_P),
    LumpedFault('w', 'F_w', 'attitude', 'rad/s^2', 'fault_true_w', 'fault_est_w',
                FALSE_ESTIMATE_THRESHOLD_W, NRMSE_FLOOR_W),
)


def fault_spec_value(spec, key: str):
    """Return the field ``key`` of a fault spec given as an object (``FaultSpec``) or as a mapping."""
    return spec[key] if isinstance(spec, dict) else getattr(spec, key)


#: The fields of a fault injection (``uh_msgs/ActuatorFault``) that make the fault.
_FAULT_FIELDS = ('channel', 'rho', 'bias_constant', 'bias_amplitude', 'bias_frequency', 'onset_time')


def injected_faults(arrays) -> list:
    """Return the faults injected during a recorded run that its simulators applied, in the order received.

    ``arrays['fault_injections']`` (:func:`uh_report.bag_metrics.read_team_bag`) holds one mapping
    per message on ``/uhN/fault``: ``uh`` (the UH of the topic), ``uh_id`` (the UH the message
    names), the fault's fields and ``received_s`` (its log time, s of simulated time). A simulator
    applies a message that names its own UH and is a valid fault, as ``uh_sim_node.sim_node`` does
    (docs/faults.md#injecting-a-fault-at-run-time); the others it rejects, and they are left out.
    Each applied one is returned as a mapping with ``uh``, the fault's fields, ``sent_onset_time``
    and ``received_s``; its ``onset_time`` is when it acts, ``max(sent onset, received)`` (a fault
    sent with an onset in the past acts from its arrival); ``nominal`` tells one that clears its
    channel (rho = 1, no bias: not a fault). A message with ``stuck_in_place`` sticks its channel where it
    is on arrival: ``rho`` 0 and ``onset_time`` its arrival, its position (the bias) not on the wire
    (``stuck_in_place`` true in the mapping).
    """
    applied = []
    for record in arrays.get('fault_injections', ()) if arrays is not None else ():
        if int(record['uh_id']) != int(record['uh']):
            continue
        try:
            fault = ActuatorFault(**{k: (int if k == 'channel' else float)(record[k]) for k in _FAULT_FIELDS})
        except (FaultError, ValueError, TypeError):
            continue
        received = float(record['received_s'])
        if record.get('stuck_in_place'):
            fault = ActuatorFault.stuck_at(fault.channel, 0.0, received)
        applied.append({'uh': int(record['uh']), **{k: getattr(fault, k) for k in _FAULT_FIELDS},
                        'onset_time': max(fault.onset_time, received), 'sent_onset_time': fault.onset_time,
                        'received_s': received, 'nominal': bool(fault.is_nominal),
                        'stuck_in_place': bool(record.get('stuck_in_place', False))})
    return applied


def run_faults(scenario, arrays=None) -> dict:
    """Return ``{uh id: fault specs}``: the faults ``scenario`` schedules and those injected during the run.

    The injected ones are those of :func:`injected_faults` (``arrays`` of a recorded run), less the
    nominal ones. A channel faulted twice keeps both: the scoring takes a channel's earliest fault.
    """
    out = {int(uh): tuple(specs) for uh, specs in scenario.faults.items()}
    for fault in injected_faults(arrays):
        if not fault['nominal']:
            out[fault['uh']] = out.get(fault['uh'], ()) + ({k: fault[k] for k in _FAULT_FIELDS},)
    return out


def fault_list(scenario, arrays=None) -> dict:
    """Return ``{'scheduled': [...], 'injected': [...]}``: the run's faults as plain mappings (``metrics.json``)."""
    scheduled = [{'uh': int(uh), **{k: fault_spec_value(spec, k) for k in _FAULT_FIELDS}}
                 for uh, specs in sorted(scenario.faults.items()) for spec in specs]
    return {'scheduled': [{k: (int(v) if k in ('uh', 'channel') else float(v)) for k, v in f.items()}
                          for f in scheduled],
            'injected': injected_faults(arrays)}


def faulted_uhs(scenario, arrays=None) -> dict:
    """``{uh id: FaultedUH}`` of the UHs with at least one fault: scheduled in ``scenario.faults``, or injected.

    Injected faults are those of :func:`run_faults` (a recorded run's ``arrays``). Accepts fault
    specs as objects or mappings with ``channel`` and ``onset_time``.
    """
    out = {}
    for uh, specs in sorted(run_faults(scenario, arrays).items()):
        specs = tuple(specs)
        if not specs:
            continue
        onset = min(float(fault_spec_value(s, 'onset_time')) for s in specs)
        collective = any(int(fault_spec_value(s, 'channel')) == 0 for s in specs)
        out[int(uh)] = FaultedUH(onset=onset, collective=collective)
    return out


def none_if_nan(x):
    """``float(x)``, or ``None`` if it is not finite (JSON ``null``)."""
    x = float(x)
    return None if not math.isfinite(x) else x


def rms_norm(vectors) -> float | None:
    """RMS of the Euclidean norms of the rows: ``sqrt(mean_k |v_k|^2)``.

    Parameters
    ----------
    vectors : array_like (k, 3)
        One vector per step, in any unit (m/s^2 for ``F_p``, rad/s^2 for ``F_w``).

    Returns
    -------
    float or None
        In the unit of ``vectors``; ``None`` without rows or if not finite.
    """
    vectors = np.asarray(vectors, dtype=float)
    if vectors.shape[0] == 0:
        return None
    return none_if_nan(math.sqrt(float(np.mean(dot(vectors, vectors)))))


def _finite_rows(*arrays) -> np.ndarray:
    """(k,) bool: the rows where every array holds finite values.

    A step a real-time run did not record is NaN and is left out of the fault metrics.
    """
    keep = np.ones(arrays[0].shape[0], dtype=bool)
    for arr in arrays:
        keep &= np.isfinite(arr).all(axis=-1)
    return keep


def _step_window(step_time, start: float, end: float | None, tolerance: float) -> np.ndarray:
    """(K,) bool: the steps with ``start <= t_k`` and, if ``end`` is given, ``t_k < end`` (s)."""
    window = step_time >= start - tolerance
    if end is not None:
        window &= step_time < end - tolerance
    return window


def _window_bounds(step_time, window) -> list | None:
    """``[t_first, t_last]`` of the steps in ``window`` (s), ``None`` if it is empty."""
    if not window.any():
        return None
    times = step_time[window]
    return [round(float(times[0]), 9), round(float(times[-1]), 9)]


def _fault_estimation_entry(estimate, truth, vector: LumpedFault) -> dict:
    """``rms_error``, ``truth_rms``, ``nrmse`` and ``nrmse_note`` of one lumped-fault vector.

    Parameters
    ----------
    estimate, truth : ndarray (k, 3)
        ``Fhat`` and ``F`` on the steps of the window, ``vector.unit``.
    vector : LumpedFault

    Returns
    -------
    dict
        ``rms_error`` = RMS of ``|Fhat - F|`` and ``truth_rms`` = RMS of ``|F|`` (``vector.unit``);
        ``nrmse`` = their ratio if ``truth_rms >= vector.nrmse_floor``, else ``None`` with the
        reason in ``nrmse_note`` (``None`` when the NRMSE is a number).
    """
    keep = _finite_rows(estimate, truth)
    estimate, truth = estimate[keep], truth[keep]
    rms_error = rms_norm(estimate - truth)
    truth_rms = rms_norm(truth)
    nrmse, note = None, None
    if rms_error is None or truth_rms is None:
        note = 'no step in the window'
    elif truth_rms < vector.nrmse_floor:
        note = (f'not meaningful: the RMS of the true {vector.symbol}, {truth_rms:.3g} {vector.unit}, is below '
                f'the floor {vector.nrmse_floor:g} {vector.unit}')
    else:
        nrmse = none_if_nan(rms_error / truth_rms)
    return {'rms_error': rms_error, 'truth_rms': truth_rms, 'nrmse': nrmse, 'nrmse_note': note}


def nrmse_below_floor(entry) -> bool:
    """Tell whether a ``fault_estimation`` vector entry withholds its NRMSE because the true RMS is below the floor.

    That is: ``nrmse`` null, ``truth_rms`` a number, as opposed to an empty window.

    Parameters
    ----------
    entry : mapping
        ``metrics["fault_estimation"]["uh<i>"]["p" or "w"]``.

    Returns
    -------
    bool
    """
    return entry.get('nrmse') is None and entry.get('truth_rms') is not None


def fault_estimation(step_time, ids, faulted, fault_data, tolerance: float) -> dict:
    """``fault_estimation`` of docs/metrics.md.

    Each faulted UH's scored vectors over ``[onset + FAULT_WINDOW_DELAY, end]``; ``fault_data`` maps array names to (K,
    n, 3) or ``None``.
    """
    out = {}
    for uh, info in faulted.items():
        vectors = info.scored_vectors()
        if any(fault_data[name] is None for v in vectors for name in (v.true_array, v.estimate_array)):
            raise MetricsError(f'UH {uh} is faulted but the true or estimated lumped faults are missing')
        col = ids.index(uh)
        window = _step_window(step_time, info.onset + FAULT_WINDOW_DELAY, None, tolerance)
        entry = {'window': _window_bounds(step_time, window)}
        for v in vectors:
            entry[v.key] = _fault_estimation_entry(fault_data[v.estimate_array][window, col],
                                                   fault_data[v.true_array][window, col], v)
        out[f'uh{uh}'] = entry
    return out


def false_fault_estimate(step_time, ids, faulted, fault_data, tolerance: float) -> dict:
    """``false_fault_estimate`` of docs/metrics.md.

    RMS of ``|Fhat|`` of every UH over ``[FALSE_ESTIMATE_START, end]`` if healthy, ``[FALSE_ESTIMATE_START, onset)`` if
    faulted (left out if empty), the maximum over the UHs and the thresholds it is checked against.
    """
    per_uh = {}
    for col, uh in enumerate(ids):
        end = faulted[uh].onset if uh in faulted else None
        window = _step_window(step_time, FALSE_ESTIMATE_START, end, tolerance)
        if not window.any():
            continue
        entry = {}
        for v in LUMPED_FAULTS:
            estimate = fault_data[v.estimate_array]
            rows = None if estimate is None else estimate[window, col]
            entry[v.key] = None if rows is None else rms_norm(rows[_finite_rows(rows)])
        entry['window'] = _window_bounds(step_time, window)
        per_uh[f'uh{uh}'] = entry
    largest = {v.key: max((e[v.key] for e in per_uh.values() if e[v.key] is not None), default=None)
               for v in LUMPED_FAULTS}
    return {**per_uh, 'max': largest, 'threshold': {v.key: v.false_estimate_threshold for v in LUMPED_FAULTS}}
