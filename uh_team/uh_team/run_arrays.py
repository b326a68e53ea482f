"""The arrays of a team run: one home for their names, shapes and the layout of the run's reference.

A run of K control steps of n UHs is held as arrays with one row per sample t_k = k dt,
k = 0..K, and the UH axis in ``scenario.ids`` order: the in-process reference simulation
(``uh_team.team_simulation``, ``timeseries.npz``) and a recorded bag read back
(``uh_report.bag_metrics.read_team_bag``) make them with :func:`new_run_arrays`, the metrics
(:mod:`uh_team.metrics`) read them.
"""
from __future__ import annotations

import numpy as np

from uh_core.layout import INPUT_SIZE, STATE_SIZE

__all__ = ['RUN_REFERENCE_SIZE', 'RUN_REF_POSITION', 'RUN_REF_YAW', 'RUN_REF_YAW_RATE', 'STEP_VECTORS',
           'new_run_arrays']

#: Columns of a run's ``reference`` array: ``(x0, y0, z0, psi0, psi0')`` of the virtual leader
#: (position m, yaw rad, yaw rate rad/s), the position first.
RUN_REFERENCE_SIZE = 5
RUN_REF_POSITION = slice(0, 3)
RUN_REF_YAW = 3
RUN_REF_YAW_RATE = 4

#: ``(name, length)`` of the per-UH vectors of a run's arrays, in their order: state (the layout of
#: ``uh_core.layout``), command (rad), true and estimated lumped faults (m/s^2, rad/s^2), designed
#: acceleration ``u_p`` (m/s^2).
STEP_VECTORS = (('states', STATE_SIZE), ('commands', INPUT_SIZE), ('fault_true_p', 3), ('fault_true_w', 3),
                ('fault_est_p', 3), ('fault_est_w', 3), ('u_p', 3))


def new_run_arrays(samples: int, n: int, with_reference: bool = True, with_z1: bool = False) -> dict:
    """Make the arrays of a run of ``samples`` samples (K + 1) of ``n`` UHs, every value not yet known.

    Parameters
    ----------
    samples : int
        Rows of every array (K + 1 for a run of K steps).
    n : int
        UHs.
    with_reference : bool
        Include ``reference`` (samples, :data:`RUN_REFERENCE_SIZE`).
    with_z1 : bool
        Include the consensus error ``z1`` (samples, n, 3) m.

    Returns
    -------
    dict
        The :data:`STEP_VECTORS` (samples, n, length) filled with NaN (a step never written stays
        NaN, as a step a real-time run did not record), ``reference`` after ``commands`` if asked,
        ``z1`` if asked, and ``saturated`` and ``safety_active`` (the safety filter changed ``u_p``,
        docs/safety.md) (samples, n) bool, False.
    """
    out = {}
    for name, length in STEP_VECTORS:
        out[name] = np.full((samples, n, length), np.nan)
        if name == 'commands' and with_reference:
            out['reference'] = np.full((samples, RUN_REFERENCE_SIZE), np.nan)
    if with_z1:
        out['z1'] = np.full((samples, n, 3), np.nan)
    out['saturated'] = np.zeros((samples, n), dtype=bool)
    out['safety_active'] = np.zeros((samples, n), dtype=bool)
    return out
