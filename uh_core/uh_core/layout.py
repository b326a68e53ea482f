"""Layouts shared by the simulator, the controller and the wire: state, input channels, reference.

One home for the index facts every side relies on (docs/model.md, "State and inputs"):

* the state vector ``x`` (12,) float64 = ``[p (3) m, v (3) m/s, Theta (3) rad, omega (3) rad/s]``
  with position and velocity in the inertial z-up frame, ZYX Euler angles ``(phi, theta, psi)``
  and body rates ``(p, q, r)`` in the body frame;
* the input vector ``u`` (4,) rad = ``(theta_col, theta_tr, delta_lat, delta_lon)``, which is also
  the order of the actuator-fault channels (the ``CHANNEL_*`` constants of
  ``uh_msgs/msg/ActuatorFault.msg``; a test checks they agree);
* the reference vector (7,) = ``[p_0 (3) m, v_0 (3) m/s, psi_0 rad]`` of the virtual leader.

The numba kernels read these module-level integers as compile-time constants.
"""
from __future__ import annotations

__all__ = [
    'STATE_SIZE', 'X_P', 'X_V', 'X_THETA', 'X_OMEGA', 'YAW', 'INPUT_SIZE', 'U_COL', 'U_TR', 'U_LAT', 'U_LON',
    'INPUT_NAMES', 'NUM_CHANNELS', 'CHANNEL_NAMES', 'CHANNEL_ALIASES', 'R_P', 'R_V', 'R_YAW', 'REFERENCE_SIZE',
]

# -- state -------------------------------------------------------------------------------------
STATE_SIZE = 12
X_P, X_V, X_THETA, X_OMEGA = 0, 3, 6, 9          # first index of p, v, Theta, omega in x
YAW = 2                                           # yaw in an Euler-angle 3-vector (phi, theta, psi)

# -- inputs and actuator channels --------------------------------------------------------------
INPUT_SIZE = 4
U_COL, U_TR, U_LAT, U_LON = 0, 1, 2, 3            # theta_col, theta_tr, delta_lat, delta_lon
#: Symbols of the four physical inputs, in channel order 0..3.
INPUT_NAMES = ('theta_col', 'theta_tr', 'delta_lat', 'delta_lon')
NUM_CHANNELS = INPUT_SIZE
#: Short names of the actuator channels (as the fault-injection CLI and ActuatorFault.msg name them).
CHANNEL_NAMES = ('collective', 'tail_rotor', 'lateral', 'longitudinal')
#: Every accepted name of a channel -> its index: the short name and the input's symbol.
CHANNEL_ALIASES = {alias: i for i in range(NUM_CHANNELS) for alias in (CHANNEL_NAMES[i], INPUT_NAMES[i])}

# -- reference of the virtual leader ----------------------------------------------------------
R_P, R_V, R_YAW = 0, 3, 6                         # p_0 (3) m, v_0 (3) m/s, psi_0 rad
REFERENCE_SIZE = 7

# -- the 3-vectors above as slices (position of a state; position and velocity of a reference) --
X_P_SLICE = slice(X_P, X_P + 3)
R_P_SLICE, R_V_SLICE = slice(R_P, R_P + 3), slice(R_V, R_V + 3)
__all__ += ['X_P_SLICE', 'R_P_SLICE', 'R_V_SLICE']
