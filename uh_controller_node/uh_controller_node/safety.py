"""The safety filter's settings as its kernel reads them (docs/safety.md).

The filter is a layer outside the control law with inputs of its own: the scenario's ``safety``
mapping (:class:`uh_topology.safety.SafetySpec`), the airframe's rotor radius, the limits of the
attitude extraction (``tilt_limit``, ``min_vertical_accel`` of the gains) it must stay within, and
the nominal drag the law already cancels. :func:`safety_parameters` packs them into the vector of
:mod:`uh_controller_node.safety_kernels`.
"""
from __future__ import annotations

import numpy as np

from uh_core.airframe import HelicopterParams

from . import safety_kernels as sk

__all__ = ['safety_parameters', 'proximity_input']


def safety_parameters(spec, nominal: HelicopterParams, tilt_limit: float, min_vertical_accel: float) -> np.ndarray:
    """Return the filter's parameter vector (``SF_*`` of :mod:`~uh_controller_node.safety_kernels`).

    Parameters
    ----------
    spec : uh_topology.safety.SafetySpec
        The scenario's ``safety`` settings.
    nominal : HelicopterParams
        The controller's nominal model (its ``D_v`` is the drag the law cancels; its
        ``rotor_radius`` sets the default minimum separation).
    tilt_limit : float
        rad.
    min_vertical_accel : float
        m/s^2.
    """
    params = np.empty(sk.SAFETY_PARAMS_SIZE)
    params[sk.SF_MIN_SEPARATION] = spec.separation(nominal.rotor_radius)
    params[sk.SF_SENSING_RADIUS] = spec.sensing_radius
    params[sk.SF_BARRIER_GAIN] = spec.barrier_gain
    params[sk.SF_BRAKE_ACCEL] = spec.brake_accel
    params[sk.SF_SLACK_WEIGHT] = spec.slack_weight
    params[sk.SF_SIDESTEP_ACCEL] = spec.sidestep_accel
    params[sk.SF_DRAG_PER_MASS] = nominal.D_v / nominal.mass
    params[sk.SF_GRAVITY] = nominal.gravity
    params[sk.SF_TILT_LIMIT] = tilt_limit
    params[sk.SF_MIN_VERTICAL_ACCEL] = min_vertical_accel
    params[sk.SF_PROXIMITY_DELAY] = spec.proximity_delay_steps
    params[sk.SF_PROXIMITY_LOSS] = spec.proximity_loss
    params[sk.SF_PROXIMITY_NOISE_P] = spec.proximity_noise_position
    params[sk.SF_PROXIMITY_NOISE_V] = spec.proximity_noise_velocity
    params[sk.SF_PROXIMITY_SEED] = spec.proximity_seed
    return params


def proximity_input(positions, velocities, own: int, sensing_radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Return UH row ``own``'s proximity input: ``[p, v]`` of every other row within ``sensing_radius`` m.

    ``positions``, ``velocities``: (n, 3) arrays, m and m/s, inertial frame (the true states: the
    plant side's sensing, docs/safety.md#what-the-filter-knows). Returns ``(rows, senders)``: the
    rows, in the order of ``positions``, and the row of ``positions`` each one is of. The same kernel
    (:func:`~uh_controller_node.safety_kernels.proximity_rows`) builds the input of the in-process
    team loop.
    """
    positions = np.ascontiguousarray(positions, dtype=float)
    velocities = np.ascontiguousarray(velocities, dtype=float)
    size = max(positions.shape[0] - 1, 1)
    out, senders = np.empty((size, sk.PROXIMITY_COLUMNS)), np.empty(size, dtype=np.int64)
    rows = sk.proximity_rows(positions, velocities, int(own), float(sensing_radius), out, senders)
    return out[:rows], senders[:rows]
