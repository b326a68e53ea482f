"""Layouts shared by the simulator, the controller and the wire: state, input channels, reference.

One home for the index facts every side relies on (docs/model.md, "State and inputs"):

* the state vector ``x`` (12,) float64 = ``[p (3) m, v (3) m/s, Theta (3) rad, omega (3) rad/s]``
  with position and velocity in the inertial z-up frame, ZYX Euler angles ``(phi, theta, psi)``
  and body rates ``(p, q, r)`` in the body frame;
* the input vector ``u`` (4,) rad = ``(theta_col, theta_tr, delta_lat, delta_lon)``, which is also
  the order of the actuator-fault channels (the ``CHANNEL_*`` constants of
  ``uh_msgs/msg/ActuatorFault.msg``; a test checks they agree);
* the reference vector (7,) = ``[p_0 (3) m, v_0 (3) m/s, psi_0 rad]`` of the virtual leader;
* the controller's status vector (STATUS_SIZE,) float64: the fields of ``uh_msgs/msg/ControllerStatus.msg``
  from ``z1`` to ``cost_rate``, in the order and with the names of the message (:data:`STATUS_FIELDS`;
  a test checks they agree). The control kernel writes it; the controller's status record (its
  fields made from this table) and the wire conversion read it by these names.

The numba kernels read these module-level integers as compile-time constants.
"""
from __future__ import annotations

from typing import NamedTuple

__all__ = [
    'STATE_SIZE', 'X_P', 'X_V', 'X_THETA', 'X_OMEGA', 'YAW', 'INPUT_SIZE', 'U_COL', 'U_TR', 'U_LAT', 'U_LON',
    'INPUT_NAMES', 'NUM_CHANNELS', 'CHANNEL_NAMES', 'CHANNEL_ALIASES', 'R_P', 'R_V', 'R_YAW', 'REFERENCE_SIZE',
    'STATUS_VECTOR3', 'STATUS_FLOAT', 'STATUS_FLAG', 'StatusField', 'STATUS_FIELDS', 'STATUS_LAYOUT', 'STATUS_WIDTH',
    'STATUS_INDEX', 'STATUS_SIZE',
    'S_Z1', 'S_Z2', 'S_Z3', 'S_Z4', 'S_F_HAT_P', 'S_F_HAT_W', 'S_ZN_P', 'S_ZN_W', 'S_U_P', 'S_EULER_D',
    'S_THRUST', 'S_W_NORM_P', 'S_W_NORM_W', 'S_SAT_TILT', 'S_SAT_COLLECTIVE', 'S_SAT_CYCLIC', 'S_COST_RATE',
    'S_SAFETY_ACTIVE', 'S_CLOSEST_DISTANCE',
    'SATURATION_FLAGS',
    'STATUS_VECTORS',
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

# -- the 3-vectors above as slices (the blocks of a state; position and velocity of a reference) --
X_P_SLICE, X_V_SLICE = slice(X_P, X_P + 3), slice(X_V, X_V + 3)
X_THETA_SLICE, X_OMEGA_SLICE = slice(X_THETA, X_THETA + 3), slice(X_OMEGA, X_OMEGA + 3)
R_P_SLICE, R_V_SLICE = slice(R_P, R_P + 3), slice(R_V, R_V + 3)
__all__ += ['X_P_SLICE', 'X_V_SLICE', 'X_THETA_SLICE', 'X_OMEGA_SLICE', 'R_P_SLICE', 'R_V_SLICE']

# -- status vector of one controller step (uh_msgs/msg/ControllerStatus.msg) -----------------------
#: Kinds of a status field: its ``.msg`` type and how many float64 entries of the vector it takes.
STATUS_VECTOR3 = 'geometry_msgs/Vector3'   # 3 entries
STATUS_FLOAT = 'float64'                   # 1 entry
STATUS_FLAG = 'bool'                       # 1 entry, 1.0 when set, else 0.0


class StatusField(NamedTuple):
    """One field of the status: its name in ``ControllerStatus.msg``, its kind, what it holds (unit, frame)."""

    name: str
    kind: str
    description: str


#: The fields of the status in the order of ``ControllerStatus.msg`` and of the vector: the one place
#: a status field is declared (besides its ``.msg`` line). The controller's status record, its
#: reader and the wire conversion follow this table.
STATUS_FIELDS = (
    StatusField('z1', STATUS_VECTOR3, 'consensus error e, m'),
    StatusField('z2', STATUS_VECTOR3, 'velocity error v - alpha_f, m/s'),
    StatusField('z3', STATUS_VECTOR3, 'attitude error Theta - Theta_df (yaw wrapped), rad'),
    StatusField('z4', STATUS_VECTOR3, 'body-rate error omega - alpha_wf, rad/s'),
    StatusField('fault_estimate_position', STATUS_VECTOR3, 'Fhat_p used this step, m/s^2'),
    StatusField('fault_estimate_attitude', STATUS_VECTOR3, 'Fhat_w used this step, rad/s^2'),
    StatusField('prediction_error_position', STATUS_VECTOR3, 'z_n = v - vhat, m/s'),
    StatusField('prediction_error_attitude', STATUS_VECTOR3, 'z_n = omega - omegahat, rad/s'),
    StatusField('u_p', STATUS_VECTOR3, 'designed acceleration (before the tilt and collective limits), m/s^2'),
    StatusField('euler_desired', STATUS_VECTOR3, 'attitude command (phi_d, theta_d, psi_d) before its filter, rad'),
    StatusField('thrust_command', STATUS_FLOAT, 'T_c before the collective limit, N'),
    StatusField('weight_norm_position', STATUS_FLOAT, 'Frobenius norm of W_p after the update'),
    StatusField('weight_norm_attitude', STATUS_FLOAT, 'Frobenius norm of W_w after the update'),
    StatusField('saturated_tilt', STATUS_FLAG, 'tilt limit or minimum vertical acceleration active'),
    StatusField('saturated_collective', STATUS_FLAG, 'collective limit active'),
    StatusField('saturated_cyclic', STATUS_FLAG, 'a cyclic or the tail-rotor limit active'),
    StatusField('cost_rate', STATUS_FLOAT, '|z1|^2 + |u_p|^2, the integrand of the CPI (docs/metrics.md)'),
    StatusField('safety_active', STATUS_FLAG, 'the safety filter changed u_p this step (docs/safety.md)'),
    StatusField('closest_distance', STATUS_FLOAT, 'hub-to-hub distance to the closest UH the proximity input '
                'reports, m; NaN when it reports none or the filter is off'),
)
#: ``(name, kind)`` of :data:`STATUS_FIELDS`.
STATUS_LAYOUT = tuple((f.name, f.kind) for f in STATUS_FIELDS)
#: Float64 entries a field of each kind takes.
STATUS_WIDTH = {STATUS_VECTOR3: 3, STATUS_FLOAT: 1, STATUS_FLAG: 1}
#: Field name -> first index of the field in the status vector.
STATUS_INDEX = {}
STATUS_SIZE = 0
for _name, _kind in STATUS_LAYOUT:
    STATUS_INDEX[_name] = STATUS_SIZE
    STATUS_SIZE += STATUS_WIDTH[_kind]
del _name, _kind
# the indices the kernels use (plain ints: numba reads them as compile-time constants)
S_Z1 = STATUS_INDEX['z1']
S_Z2 = STATUS_INDEX['z2']
S_Z3 = STATUS_INDEX['z3']
S_Z4 = STATUS_INDEX['z4']
S_F_HAT_P = STATUS_INDEX['fault_estimate_position']
S_F_HAT_W = STATUS_INDEX['fault_estimate_attitude']
S_ZN_P = STATUS_INDEX['prediction_error_position']
S_ZN_W = STATUS_INDEX['prediction_error_attitude']
S_U_P = STATUS_INDEX['u_p']
S_EULER_D = STATUS_INDEX['euler_desired']
S_THRUST = STATUS_INDEX['thrust_command']
S_W_NORM_P = STATUS_INDEX['weight_norm_position']
S_W_NORM_W = STATUS_INDEX['weight_norm_attitude']
S_SAT_TILT = STATUS_INDEX['saturated_tilt']
S_SAT_COLLECTIVE = STATUS_INDEX['saturated_collective']
S_SAT_CYCLIC = STATUS_INDEX['saturated_cyclic']
S_COST_RATE = STATUS_INDEX['cost_rate']
S_SAFETY_ACTIVE = STATUS_INDEX['safety_active']
S_CLOSEST_DISTANCE = STATUS_INDEX['closest_distance']
#: The saturation flags of the status (its ``STATUS_FLAG`` fields, ``saturated_*``), in order.
SATURATION_FLAGS = tuple(name for name, kind in STATUS_LAYOUT if kind == STATUS_FLAG)
#: Number of 3-vector fields; they come first and fill ``status[:3 * STATUS_VECTORS]``.
STATUS_VECTORS = sum(kind == STATUS_VECTOR3 for _, kind in STATUS_LAYOUT)
