"""What the arrays of the control law hold, and where: its parameter vector, memory and status.

The kernels of the law (:mod:`.control_kernels`, :mod:`.loop_kernels`, :mod:`.learning_kernels`)
read these tables as numba compile-time constants; this module has no kernel of its own.

Arrays
------
* ``params`` (CONTROL_PARAMS_SIZE,) the nominal model and the gains, built by
  :func:`control_parameters`: the entries of :data:`MODEL_ENTRIES` (SI units), then the gains with
  a slot (:data:`GAIN_ENTRIES`, declared in :data:`uh_controller_node.gains.GAINS`), then one block
  of :data:`LOOP_GAIN_ENTRIES` per loop. :data:`PARAM` holds the first index of each entry and of
  each loop's block (``PARAM.mass``, ``PARAM.beta``, ``PARAM.inner``), :data:`LOOP` the offset of
  each gain inside a block (``params[PARAM.inner + LOOP.kappa]`` is kappa_w). Both are made from
  the tables, so a gain declared in ``gains.py`` has its slot and its index without another line.
* ``memory`` (MEMORY_ROWS = 8, 3): rows ``M_ALPHA_F`` alpha_f m/s, ``M_V_HAT`` vhat m/s,
  ``M_F_HAT_P`` Fhat_p m/s^2, ``M_THETA_DF`` Theta_df rad, ``M_ALPHA_WF`` alpha_wf rad/s,
  ``M_OMEGA_HAT`` omegahat rad/s, ``M_F_HAT_W`` Fhat_w rad/s^2, and ``M_FLAGS`` whose column
  ``FLAG_STARTED`` is 1.0 once the first step has initialised the filters and estimation models
  (all zeros = a fresh controller) and whose column ``FLAG_TIME`` is the simulated time of the step.
* ``status`` (STATUS_SIZE,), laid out by :data:`uh_core.layout.STATUS_FIELDS` (the fields of
  ``ControllerStatus.msg``); :data:`STATUS` holds the first index of each field by its name
  (``STATUS.z1``, ``STATUS.cost_rate``), so a status field declared in the layout (and the ``.msg``)
  is written by the kernel without an index constant of its own.

:data:`PARAM`, :data:`LOOP` and :data:`STATUS` are named tuples of plain ints: numba freezes a
global tuple into the compiled code, so ``params[base + LOOP.kappa]`` compiles to the same constant
offset as an integer constant would.
"""
from __future__ import annotations

import operator
import re
from collections import namedtuple
from typing import NamedTuple

import numpy as np

from uh_core.layout import INPUT_SIZE, STATUS_INDEX

from .gains import GAIN_SLOTS, LOOP_GAIN_SLOTS

__all__ = ['MODEL_ENTRIES', 'GAIN_ENTRIES', 'LOOP_GAIN_ENTRIES', 'MODEL_INDEX', 'GAIN_INDEX', 'LOOP_GAIN_OFFSET',
           'LOOP_GAINS_SIZE', 'CONTROL_PARAMS_SIZE', 'PARAM', 'LOOP', 'STATUS', 'index_table',
           'M_ALPHA_F', 'M_V_HAT', 'M_F_HAT_P', 'M_THETA_DF', 'M_ALPHA_WF', 'M_OMEGA_HAT', 'M_F_HAT_W', 'M_FLAGS',
           'FLAG_STARTED', 'FLAG_TIME', 'MEMORY_ROWS', 'ControlArrays', 'control_parameters']

# -- control parameters: the one table of what params holds, in order ----------------------------
#: Entries from the nominal model (docs/model.md#what-the-controller-knows), a ``HelicopterParams``:
#: ``(field, number of entries)``. SI units: kg, m/s^2, kg m^2 (J_x, J_y, J_z), N/rad and N (thrust
#: map T = c_M1 theta_col + c_M2), N m/rad (hub stiffness), m (hub height), rad/rad (flapping gains),
#: s (flapping lag per body rate), N m/rad (tail rotor), N m s (yaw damping), m (torque reaction per
#: thrust) and N s/m (drag), both after the model mismatch; input limits in command order (U_*), rad.
MODEL_ENTRIES = (('mass', 1), ('gravity', 1), ('inertia', 3), ('c_M1', 1), ('c_M2', 1), ('K_beta', 1), ('h_M', 1),
                 ('B_lat', 1), ('A_lon', 1), ('tau_f', 1), ('K_tr', 1), ('D_r', 1), ('c_Q', 1), ('D_v', 1),
                 ('input_lower', INPUT_SIZE), ('input_upper', INPUT_SIZE))
#: Entries from the gains of the case (docs/control_law.md), a ``ControllerGains``, after the model's,
#: then one block per loop (a ``LoopGains``; dotted: a field of its ``rbf``) at offsets 0, 1, ...:
#: the gains with a slot, in the order of their declaration (``uh_controller_node.gains.GAINS``,
#: which gives their units). The outer loop has no ``tau_rate`` (None: 0).
GAIN_ENTRIES = GAIN_SLOTS
LOOP_GAIN_ENTRIES = LOOP_GAIN_SLOTS


def _first_indices(entries, start=0):
    """``{name: first index}`` of ``entries`` (names, or ``(name, count)``) laid end to end from ``start``."""
    out = {}
    for entry in entries:
        name, count = entry if isinstance(entry, tuple) else (entry, 1)
        out[name] = start
        start += count
    return out


def index_table(type_name: str, first_index: dict):
    """Return a named tuple of the ints ``first_index``, a field per name (``rbf.low`` becomes ``rbf_low``)."""
    fields = [re.sub(r'\W', '_', name) for name in first_index]
    return namedtuple(type_name, fields)(*(int(index) for index in first_index.values()))


MODEL_INDEX = _first_indices(MODEL_ENTRIES)
GAIN_INDEX = _first_indices(GAIN_ENTRIES, start=sum(count for _, count in MODEL_ENTRIES))
LOOP_GAIN_OFFSET = _first_indices(LOOP_GAIN_ENTRIES)
LOOP_GAINS_SIZE = len(LOOP_GAIN_ENTRIES)
_OUTER = GAIN_INDEX[GAIN_ENTRIES[0]] + len(GAIN_ENTRIES)   # first entry of the outer loop's gains block
CONTROL_PARAMS_SIZE = _OUTER + 2 * LOOP_GAINS_SIZE
#: First index in ``params`` of each model entry, each gain with a slot and each loop's block (``outer``, ``inner``).
PARAM = index_table('ParamIndex', {**MODEL_INDEX, **GAIN_INDEX, 'outer': _OUTER, 'inner': _OUTER + LOOP_GAINS_SIZE})
#: Offset of each loop gain with a slot inside a loop's block of ``params``.
LOOP = index_table('LoopGainOffset', LOOP_GAIN_OFFSET)
#: First index in ``status`` of each field of the status (``uh_core.layout.STATUS_INDEX``).
STATUS = index_table('StatusIndex', STATUS_INDEX)

# -- memory: the internal states of one controller, one 3-vector per row ------------------------
M_ALPHA_F = 0               # filtered virtual velocity alpha_f, m/s, inertial
M_V_HAT = 1                 # outer SPEM state vhat, m/s
M_F_HAT_P = 2               # outer fault estimate Fhat_p, m/s^2, inertial
M_THETA_DF = 3              # filtered attitude command Theta_df, rad (continuous, not wrapped)
M_ALPHA_WF = 4              # filtered virtual body rate alpha_wf, rad/s
M_OMEGA_HAT = 5             # inner SPEM state omegahat, rad/s
M_F_HAT_W = 6               # inner fault estimate Fhat_w, rad/s^2, body
M_FLAGS = 7                 # flags and clock: columns FLAG_STARTED, FLAG_TIME
FLAG_STARTED = 0            # 1.0 after the first step
FLAG_TIME = 1               # simulated time t_k of the step being computed, s (set by the caller on
                            # the first step, k dt; advanced by dt per step): ends the learning phase
MEMORY_ROWS = 8


class ControlArrays(NamedTuple):
    """The arrays of one controller that ``uh_control_step`` reads or updates (see module doc).

    Attributes
    ----------
    params : ndarray (CONTROL_PARAMS_SIZE,)
    offset : ndarray (3,)
        Own formation offset h_i, m (zero for followers).
    neighbour_weights : ndarray (n_nb,)
        a_ij of the UHs heard, ascending id.
    neighbour_offsets : ndarray (n_nb, 3)
        Their formation offsets h_j, m (zero for followers).
    leader_link : float
        a_i0.
    weights_p : ndarray (mu_p, 3)
    weights_w : ndarray (mu_w, 3)
    memory : ndarray (MEMORY_ROWS, 3)
    safety : ndarray (SAFETY_PARAMS_SIZE,) or (0,)
        The safety filter's parameters (:mod:`~uh_controller_node.safety_kernels`); empty when it is off.
    """

    params: np.ndarray
    offset: np.ndarray
    neighbour_weights: np.ndarray
    neighbour_offsets: np.ndarray
    leader_link: float
    weights_p: np.ndarray
    weights_w: np.ndarray
    memory: np.ndarray
    safety: np.ndarray


def control_parameters(gains, model) -> np.ndarray:
    """Pack ``params`` (CONTROL_PARAMS_SIZE,) float64 from the gains of one case and the nominal model.

    The entries follow :data:`MODEL_ENTRIES`, :data:`GAIN_ENTRIES` and, per loop, :data:`LOOP_GAIN_ENTRIES`.

    Parameters
    ----------
    gains : uh_controller_node.gains.ControllerGains
    model : uh_core.airframe.HelicopterParams
    """
    out = np.zeros(CONTROL_PARAMS_SIZE)
    for name, count in MODEL_ENTRIES:
        at = MODEL_INDEX[name]
        out[at:at + count] = getattr(model, name)
    for name in GAIN_ENTRIES:
        out[GAIN_INDEX[name]] = getattr(gains, name)
    for base, loop in ((PARAM.outer, gains.outer), (PARAM.inner, gains.inner)):
        for path in LOOP_GAIN_ENTRIES:
            value = operator.attrgetter(path)(loop)
            out[base + LOOP_GAIN_OFFSET[path]] = 0.0 if value is None else value   # outer tau_rate: None
    return out
