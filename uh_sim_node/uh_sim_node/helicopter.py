"""Six-degree-of-freedom unmanned-helicopter model with actuator faults (docs/model.md, docs/faults.md).

Frames and units
----------------
Inertial frame z-up; ZYX Euler angles ``Theta = (phi, theta, psi)`` rad with
``R = Rz(psi) Ry(theta) Rx(phi)`` (body -> inertial); body rates ``omega = (p, q, r)`` rad/s in the
body frame. State vector ``x`` (12,) float64 = ``[p (3) m, v (3) m/s, Theta (3) rad, omega (3) rad/s]``.
Input vector ``u`` (4,) rad = ``(theta_col, theta_tr, delta_lat, delta_lon)``
(:data:`uh_core.layout.INPUT_NAMES`).

Dynamics (docs/model.md, "Helicopter dynamics")::

    p' = v
    m v' = -m g e3 + T_M R e3 - D_v v + d_p(t)
    Theta' = H(Theta) omega
    J omega' = -omega x J omega + Gamma
    T_M = c_M1 theta_col + c_M2
    b_1s = B_lat delta_lat - tau_f p ,  a_1s = A_lon delta_lon - tau_f q
    Gamma = [(K_beta + T_M h_M) b_1s, (K_beta + T_M h_M) a_1s, K_tr theta_tr - D_r r - c_Q T_M]

with ``J = diag(inertia)``.

Inputs, limits and faults
-------------------------
The plant holds the command ``u_k`` over ``[t_k, t_k + dt)``. The chain is::

    u_cmd = clip(u_k)                   # actuator position limits (what the controller asked for)
    u_actual = clip(faults(u_cmd, t))   # paper eq. 6, then the same physical limits again

The limits are applied again after the fault because a biased actuator still cannot leave its
mechanical travel. The true lumped faults (docs/model.md, "Lumped faults") are the difference
between the dynamics with ``u_actual`` and with ``u_cmd``::

    F_p = (T_M(u_actual) - T_M(u_cmd)) / m  R e3                       m/s^2, inertial
    F_w = J^-1 (Gamma(omega, u_actual) - Gamma(omega, u_cmd))          rad/s^2, body

Rate limits of the actuators are not modelled (the command is a zero-order hold per control period).

Integration is classical RK4 with ``substeps`` equal substeps per control period; the faulted inputs
and the disturbance are evaluated at the RK4 stage times (RK4 of the non-autonomous system). A fault
switches on at a substep boundary (its activity is decided at the substep's start time), so the
input is smooth inside every substep and the scheme keeps its fourth order.
The mathematics (rates, RK4, eq. 6 with the limits, disturbance, lumped faults) lives in the
compiled kernels of :mod:`uh_sim_node.plant_kernels`; the airframe parameters in
:mod:`uh_core.airframe`. This module holds the hover trim, the force disturbance and
:class:`HelicopterPlant`, a thin wrapper around those kernels.
"""
from __future__ import annotations

import math

import numpy as np

from uh_core.airframe import HelicopterParams, load_helicopter_params
from uh_core.layout import INPUT_SIZE, STATE_SIZE

from . import plant_kernels as _k
from .faults import ActuatorFault, FaultError, FaultSchedule

__all__ = ['hover_trim', 'SinusoidalDisturbance', 'disturbance_from_spec', 'HelicopterPlant', 'plant_from_scenario']

# ---------------------------------------------------------------------------------------------
# Trim


def hover_trim(params: HelicopterParams) -> np.ndarray:
    """Return the inputs (4,) rad that hold a level hover at rest (at any heading: the model is symmetric in yaw).

    ``T_M = m g`` gives ``theta_col = (m g - c_M2) / c_M1``; zero yaw moment gives
    ``theta_tr = c_Q m g / K_tr``; zero cyclics.
    """
    mg = params.mass * params.gravity
    return np.array([(mg - params.c_M2) / params.c_M1, params.c_Q * mg / params.K_tr, 0.0, 0.0])


# ---------------------------------------------------------------------------------------------
# Disturbance


class SinusoidalDisturbance:
    """Bounded force disturbance ``d_p(t)_a = amplitude_a sin(frequency_a t + phase_a)`` N per axis.

    Parameters
    ----------
    amplitude : array_like (3,)
        N, inertial frame (bound of each component).
    frequency : array_like (3,)
        rad/s.
    phase : array_like (3,)
        rad.

    Calling the object with time ``t`` s returns a tuple of 3 floats (N). The plant does not call
    it: it evaluates the same formula in its kernels from
    :func:`uh_sim_node.plant_kernels.disturbance_table`, built when the disturbance is assigned.
    """

    __slots__ = ('amplitude', 'frequency', 'phase', '_zero')

    def __init__(self, amplitude, frequency, phase=(0.0, 0.0, 0.0)):
        self.amplitude = tuple(float(v) for v in amplitude)
        self.frequency = tuple(float(v) for v in frequency)
        self.phase = tuple(float(v) for v in phase)
        if not (len(self.amplitude) == len(self.frequency) == len(self.phase) == 3):
            raise ValueError('disturbance amplitude, frequency and phase need 3 components each')
        if not all(math.isfinite(v) for v in self.amplitude + self.frequency + self.phase):
            raise ValueError('disturbance parameters must be finite')
        self._zero = all(a == 0.0 for a in self.amplitude)

    def __call__(self, t: float) -> tuple:
        """Return the force at time ``t`` s: 3 floats, N, inertial frame."""
        if self._zero:
            return (0.0, 0.0, 0.0)
        a, w, ph = self.amplitude, self.frequency, self.phase
        return (a[0] * math.sin(w[0] * t + ph[0]),
                a[1] * math.sin(w[1] * t + ph[1]),
                a[2] * math.sin(w[2] * t + ph[2]))

    def __repr__(self) -> str:
        return (f'SinusoidalDisturbance(amplitude={self.amplitude}, frequency={self.frequency}, '
                f'phase={self.phase})')


def disturbance_from_spec(spec, uh_id: int) -> SinusoidalDisturbance | None:
    """Disturbance of UH ``uh_id`` from a scenario ``DisturbanceSpec`` (``None`` when zero).

    The phase of UH ``i`` is ``phase + i * phase_per_id`` so that the UHs are not disturbed in unison.
    """
    if spec is None or not np.any(np.asarray(spec.amplitude) != 0.0):
        return None
    phase = np.asarray(spec.phase, dtype=float) + uh_id * float(spec.phase_per_id)
    return SinusoidalDisturbance(spec.amplitude, spec.frequency, phase)


# ---------------------------------------------------------------------------------------------
# Plant


class HelicopterPlant:
    """One simulated helicopter: state, faults, disturbance and RK4 integration.

    A thin wrapper around :mod:`uh_sim_node.plant_kernels`: it holds the state as a (12,) float64
    array and the kernel arrays of its parameters, faults and disturbance, checks inputs once and
    calls the compiled kernels.

    Parameters
    ----------
    params : HelicopterParams
        True parameters of this airframe.
    faults : FaultSchedule, optional
        Actuator faults (none when ``None``). The schedule object is kept, so faults added to it
        later (fault injection) act from the next step on (the kernel table is rebuilt when
        ``faults.revision`` changes).
    x0 : array_like (12,), optional
        Initial state (default: origin, at rest, level).
    substeps : int
        RK4 substeps per control period (>= 1).
    disturbance : SinusoidalDisturbance, optional
        Force ``d_p(t)``, N, inertial frame, evaluated by the kernels at the RK4 stage times
        (none when ``None``).

    Raises
    ------
    ValueError
        ``substeps`` not an int >= 1, a state that is not 12 finite numbers, or a disturbance that
        is neither ``None`` nor a :class:`SinusoidalDisturbance`.
    FaultError
        ``faults`` not a :class:`FaultSchedule`.
    """

    def __init__(self, params: HelicopterParams, faults: FaultSchedule | None = None, x0=None,
                 substeps: int = 5, disturbance: SinusoidalDisturbance | None = None):
        if isinstance(substeps, bool) or not isinstance(substeps, (int, np.integer)) or substeps < 1:
            raise ValueError(f'substeps must be an int >= 1, got {substeps!r}')
        self.substeps = int(substeps)
        self.params = params
        self.faults = faults
        self.disturbance = disturbance
        self.reset(np.zeros(STATE_SIZE) if x0 is None else x0)

    # -- configuration ----------------------------------------------------------------------
    @property
    def params(self) -> HelicopterParams:
        """True parameters of the airframe (assigning rebuilds the kernel parameter vector)."""
        return self._params

    @params.setter
    def params(self, params: HelicopterParams) -> None:
        self._params = params
        self._params_vec = _k.params_vector(params)

    @property
    def faults(self) -> FaultSchedule:
        """The fault schedule; ``add``/``clear`` on it take effect from the next kernel call."""
        return self._faults

    @faults.setter
    def faults(self, faults: FaultSchedule | None) -> None:
        if faults is None:
            faults = FaultSchedule()
        if not isinstance(faults, FaultSchedule):
            raise FaultError(f'HelicopterPlant faults must be a FaultSchedule or None, '
                             f'got {type(faults).__name__}')
        self._faults = faults
        self._fault_revision = faults.revision
        self._fault_table = _k.fault_table(faults)

    def _fault_array(self) -> np.ndarray:
        """Return the kernel fault table, rebuilt when the schedule changed since it was built."""
        if self._faults.revision != self._fault_revision:
            self._fault_table = _k.fault_table(self._faults)
            self._fault_revision = self._faults.revision
        return self._fault_table

    @property
    def disturbance(self) -> SinusoidalDisturbance | None:
        """The force disturbance ``d_p(t)`` N, inertial (``None``: no force).

        Assigning rebuilds the kernel disturbance table.

        Raises
        ------
        ValueError
            On assigning anything but a :class:`SinusoidalDisturbance` or ``None`` (the kernels
            evaluate the sinusoid themselves; they cannot call Python code).
        """
        return self._disturbance

    @disturbance.setter
    def disturbance(self, disturbance: SinusoidalDisturbance | None) -> None:
        if disturbance is not None and not isinstance(disturbance, SinusoidalDisturbance):
            raise ValueError(f'disturbance must be a SinusoidalDisturbance or None, '
                             f'got {type(disturbance).__name__}')
        self._disturbance = disturbance
        self._dist_table = _k.disturbance_table(disturbance)

    def kernel_arrays(self) -> _k.PlantArrays:
        """Return copies of the arrays the kernels take for this plant (see :mod:`.plant_kernels`)."""
        return _k.PlantArrays(self._params_vec.copy(), self._fault_array().copy(), self._dist_table.copy(),
                              self.substeps)

    # -- state ------------------------------------------------------------------------------
    def reset(self, x0) -> None:
        """Set the state to ``x0`` (12,)."""
        arr = np.array(x0, dtype=float).reshape(-1)
        if arr.shape != (STATE_SIZE,) or not np.all(np.isfinite(arr)):
            raise ValueError(f'helicopter state must be 12 finite numbers, got {np.shape(x0)}')
        self._x = arr

    @property
    def x(self) -> np.ndarray:
        """Current state (12,) float64 (a fresh array)."""
        return self._x.copy()

    # -- inputs -----------------------------------------------------------------------------
    @staticmethod
    def _command(u_cmd) -> np.ndarray:
        """Return ``u_cmd`` as a writable C-contiguous float64 (4,) array.

        No copy is made when it already is one; a read-only array would make numba compile another
        specialisation of every kernel.
        """
        u = np.ascontiguousarray(u_cmd, dtype=np.float64)
        if u.shape != (INPUT_SIZE,):
            raise ValueError(f'command u_cmd must have 4 elements (theta_col, theta_tr, delta_lat, '
                             f'delta_lon), got shape {np.shape(u_cmd)}')
        if not u.flags.writeable:
            u = u.copy()
        return u

    def _inputs(self, u_cmd, t: float) -> tuple:
        uc, ua = np.empty(INPUT_SIZE), np.empty(INPUT_SIZE)
        _k.actual_inputs(self._command(u_cmd), float(t), float(t), self._params_vec, self._fault_array(), uc, ua)
        return uc, ua

    def commanded_inputs(self, u_cmd) -> np.ndarray:
        """``u_cmd`` (4,) rad after the input limits."""
        return self._inputs(u_cmd, 0.0)[0]

    def actual_inputs(self, u_cmd, t: float) -> np.ndarray:
        """Return the inputs (4,) rad acting at time ``t`` s: limits, faults (eq. 6), limits again."""
        return self._inputs(u_cmd, t)[1]

    def stick(self, channel: int, u_cmd, t: float):
        """Stick actuator ``channel`` from ``t`` s on where the command ``u_cmd`` (4,) rad holds it then; the fault.

        :func:`.plant_kernels.stuck_position`; the channel's earlier fault is replaced.
        """
        position = _k.stuck_position(self._params_vec, self._fault_array(), channel, self._command(u_cmd), t)
        fault = ActuatorFault.stuck_at(channel, position, float(t))
        self._faults.add(fault)
        return fault

    def fault_active(self, t: float) -> bool:
        """Return True when any fault channel is past its onset at ``t`` s."""
        return self._faults.active(t)

    def stuck(self, t: float) -> bool:
        """Return True when an active channel is stuck (``rho = 0``, not compensable)."""
        return self._faults.stuck(t)

    def _force(self, t: float) -> np.ndarray:
        """Force disturbance (3,) N at ``t`` s."""
        out = np.empty(3)
        _k.force_disturbance(self._dist_table, t, out)
        return out

    def lumped_faults(self, u_cmd, t: float) -> tuple:
        """Return the true lumped faults ``(F_p (3,) m/s^2 inertial, F_w (3,) rad/s^2 body)``.

        They are taken at the current state and time ``t`` s (docs/model.md, "Lumped faults");
        exactly zero when no fault acts.

        ``u_cmd`` is the controller's command (4,) rad; it is limited first.
        """
        f_p, f_w = np.empty(3), np.empty(3)
        _k.lumped_faults(self._x, self._command(u_cmd), float(t), self._params_vec, self._fault_array(), f_p, f_w)
        return f_p, f_w

    def derivative(self, u_cmd, t: float) -> np.ndarray:
        """State derivative (12,) at the current state for command ``u_cmd`` at time ``t``."""
        t = float(t)
        _, ua = self._inputs(u_cmd, t)
        out = np.empty(STATE_SIZE)
        _k.state_derivative(self._x, ua, self._force(t), self._params_vec, out)
        return out

    # -- integration ------------------------------------------------------------------------
    def step(self, u_cmd, t: float, dt: float) -> np.ndarray:
        """Advance from ``t`` to ``t + dt`` s holding ``u_cmd`` (4,) rad; returns the new state (12,).

        ``u_cmd`` is limited, then faults and limits are applied at each RK4 stage time
        (kernel :func:`.plant_kernels.plant_step`).
        """
        _k.plant_step(self._x, self._command(u_cmd), float(t), float(dt), self.substeps, self._params_vec,
                      self._fault_array(), self._dist_table)
        return self._x.copy()


def plant_from_scenario(scenario, uh_id: int, params: HelicopterParams | None = None) -> HelicopterPlant:
    """Build the plant of UH ``uh_id`` of a ``uh_topology`` ``Scenario``.

    Its initial state, faults, disturbance and substeps come from the scenario; ``params`` default
    to the scenario's helicopter file.
    """
    if params is None:
        params = load_helicopter_params(scenario.helicopter)
    return HelicopterPlant(
        params,
        FaultSchedule.from_specs(scenario.faults.get(uh_id, ())),
        scenario.initial_states[uh_id],
        substeps=scenario.substeps,
        disturbance=disturbance_from_spec(scenario.disturbance, uh_id),
    )
