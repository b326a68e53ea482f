"""Six-degree-of-freedom unmanned-helicopter model with actuator faults (DESIGN.md 2.1, 2.2).

Frames and units
----------------
Inertial frame z-up; ZYX Euler angles ``Theta = (phi, theta, psi)`` rad with
``R = Rz(psi) Ry(theta) Rx(phi)`` (body -> inertial); body rates ``omega = (p, q, r)`` rad/s in the
body frame. State vector ``x`` (12,) float64 = ``[p (3) m, v (3) m/s, Theta (3) rad, omega (3) rad/s]``.
Input vector ``u`` (4,) rad = ``(theta_col, theta_tr, delta_lat, delta_lon)`` (:data:`INPUT_NAMES`).

Dynamics (DESIGN.md 2.1)::

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
mechanical travel. The true lumped faults of DESIGN.md 2.2 are the difference between the dynamics
with ``u_actual`` and with ``u_cmd``::

    F_p = (T_M(u_actual) - T_M(u_cmd)) / m  R e3                       m/s^2, inertial
    F_w = J^-1 (Gamma(omega, u_actual) - Gamma(omega, u_cmd))          rad/s^2, body

Rate limits of the actuators are not modelled (the command is a zero-order hold per control period).

Integration is classical RK4 with ``substeps`` equal substeps per control period; the faulted inputs
and the disturbance are evaluated at the RK4 stage times (RK4 of the non-autonomous system). A fault
switches on at a substep boundary (its activity is decided at the substep's start time), so the
input is smooth inside every substep and the scheme keeps its fourth order.
The mathematics (rates, RK4, eq. 6 with the limits, disturbance, lumped faults) lives in the
compiled kernels of :mod:`uh_sim_node.plant_kernels`; this module holds the parameters, the numpy
helpers of the kinematics and :class:`HelicopterPlant`, a thin wrapper around those kernels.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import yaml

from . import plant_kernels as _k
from .faults import FaultError, FaultSchedule

__all__ = [
    'INPUT_NAMES', 'STATE_SIZE', 'INPUT_SIZE', 'HelicopterParamsError', 'HelicopterParams',
    'load_helicopter_params', 'default_params_path', 'rotation_matrix', 'euler_rate_matrix',
    'clip_inputs', 'hover_trim', 'thrust', 'rotor_moments', 'state_derivative',
    'lumped_faults', 'SinusoidalDisturbance', 'disturbance_from_spec', 'HelicopterPlant',
    'plant_from_scenario',
]

#: Names of the four physical inputs, in channel order 0..3.
INPUT_NAMES = ('theta_col', 'theta_tr', 'delta_lat', 'delta_lon')
STATE_SIZE = _k.STATE_SIZE
INPUT_SIZE = _k.INPUT_SIZE

_CONFIG_DIR = Path(__file__).resolve().parent / 'config'

_SCALAR_FIELDS = ('mass', 'gravity', 'c_M1', 'c_M2', 'K_beta', 'h_M', 'B_lat', 'A_lon', 'tau_f',
                  'K_tr', 'D_r', 'c_Q', 'D_v')
_POSITIVE_FIELDS = ('mass', 'gravity', 'c_M1', 'K_beta', 'B_lat', 'A_lon', 'K_tr')
_NONNEGATIVE_FIELDS = ('h_M', 'tau_f', 'D_r', 'c_Q', 'D_v')
_VECTOR_FIELDS = {'inertia': 3, 'input_lower': 4, 'input_upper': 4}


class HelicopterParamsError(ValueError):
    """Invalid helicopter parameters (file, key, type or value)."""


def _readonly(values, size: int, name: str) -> np.ndarray:
    arr = np.array(values, dtype=float).reshape(-1)
    if arr.shape != (size,):
        raise HelicopterParamsError(f'helicopter parameter {name!r} must have {size} elements, '
                                    f'got shape {np.shape(values)}')
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class HelicopterParams:
    """Physical parameters and input limits of one helicopter (DESIGN.md 2.1).

    Attributes
    ----------
    mass : float
        m, kg.
    inertia : ndarray (3,)
        Principal moments of inertia (J_x, J_y, J_z), kg m^2 (``J = diag(inertia)``).
    gravity : float
        g, m/s^2.
    c_M1 : float
        Thrust gain, N/rad (``T_M = c_M1 theta_col + c_M2``).
    c_M2 : float
        Thrust offset, N.
    K_beta : float
        Rotor hub spring stiffness, N m/rad.
    h_M : float
        Main-rotor hub height above the centre of gravity, m.
    B_lat, A_lon : float
        Flapping gains of lateral / longitudinal cyclic, rad/rad.
    tau_f : float
        Flapping time constant, s (flapping lag per body rate).
    K_tr : float
        Tail-rotor yaw-moment gain, N m/rad.
    D_r : float
        Yaw damping, N m s.
    c_Q : float
        Main-rotor torque reaction per thrust, m (N m per N).
    D_v : float
        Translational drag, N s/m.
    input_lower, input_upper : ndarray (4,)
        Position limits of ``(theta_col, theta_tr, delta_lat, delta_lon)``, rad.
    """

    mass: float
    inertia: np.ndarray
    gravity: float
    c_M1: float
    c_M2: float
    K_beta: float
    h_M: float
    B_lat: float
    A_lon: float
    tau_f: float
    K_tr: float
    D_r: float
    c_Q: float
    D_v: float
    input_lower: np.ndarray
    input_upper: np.ndarray

    def __post_init__(self):
        for name in _SCALAR_FIELDS:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
                raise HelicopterParamsError(f'helicopter parameter {name!r} must be a real number, '
                                            f'got {value!r}')
            value = float(value)
            if not math.isfinite(value):
                raise HelicopterParamsError(f'helicopter parameter {name!r} must be finite, got {value!r}')
            if name in _POSITIVE_FIELDS and value <= 0.0:
                raise HelicopterParamsError(f'helicopter parameter {name!r} must be > 0, got {value!r}')
            if name in _NONNEGATIVE_FIELDS and value < 0.0:
                raise HelicopterParamsError(f'helicopter parameter {name!r} must be >= 0, got {value!r}')
            object.__setattr__(self, name, value)
        for name, size in _VECTOR_FIELDS.items():
            arr = _readonly(getattr(self, name), size, name)
            if not np.all(np.isfinite(arr)):
                raise HelicopterParamsError(f'helicopter parameter {name!r} must be finite, got {arr.tolist()}')
            object.__setattr__(self, name, arr)
        if np.any(self.inertia <= 0.0):
            raise HelicopterParamsError(f'helicopter parameter "inertia" must be > 0 on every axis, '
                                        f'got {self.inertia.tolist()} kg m^2')
        if np.any(self.input_lower >= self.input_upper):
            bad = [INPUT_NAMES[i] for i in range(4) if self.input_lower[i] >= self.input_upper[i]]
            raise HelicopterParamsError(f'input limits must satisfy input_lower < input_upper; '
                                        f'violated for {bad}')

    def scaled(self, **factors: float) -> 'HelicopterParams':
        """Copy with named parameters multiplied by factors, e.g. ``p.scaled(D_v=0.9, c_Q=0.9)``.

        Used for the controller's nominal model with mismatch (DESIGN.md 2.1).
        """
        changes = {}
        for name, factor in factors.items():
            if name not in _SCALAR_FIELDS and name not in _VECTOR_FIELDS:
                raise HelicopterParamsError(f'cannot scale unknown helicopter parameter {name!r}; '
                                            f'known: {", ".join(_SCALAR_FIELDS + tuple(_VECTOR_FIELDS))}')
            changes[name] = getattr(self, name) * float(factor)
        return dataclasses.replace(self, **changes)

    def nominal(self, mismatch: float) -> 'HelicopterParams':
        """The controller's nominal model: ``D_v`` and ``c_Q`` scaled by ``mismatch`` (DESIGN.md 2.1)."""
        return self.scaled(D_v=mismatch, c_Q=mismatch)

    def as_dict(self) -> dict:
        """Plain mapping (floats and lists) with the YAML keys."""
        out = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            out[f.name] = value.tolist() if isinstance(value, np.ndarray) else value
        return out


def default_params_path() -> Path:
    """Path of the bundled ``uh_sim_node/config/helicopter.yaml``."""
    return _CONFIG_DIR / 'helicopter.yaml'


def _resolve_params_path(path) -> Path:
    if path is None:
        return default_params_path()
    text = str(path)
    p = Path(text)
    # A bare name such as 'helicopter' selects a bundled config file.
    if p.suffix == '' and p.parent == Path('.') and not p.exists():
        return _CONFIG_DIR / f'{text}.yaml'
    return p


def load_helicopter_params(path=None) -> HelicopterParams:
    """Load :class:`HelicopterParams` from YAML.

    Parameters
    ----------
    path : str or Path, optional
        A YAML file, or a bare name of a bundled file in ``uh_sim_node/config`` (``'helicopter'``).
        Default: the bundled ``helicopter.yaml``. The file holds one mapping with exactly the
        fields of :class:`HelicopterParams` (numbers; ``inertia`` 3 numbers; limits 4 numbers).

    Raises
    ------
    HelicopterParamsError
        Missing file, YAML syntax error, unknown or missing key, wrong type or value.
    """
    p = _resolve_params_path(path)
    try:
        text = p.read_text()
    except OSError as exc:
        raise HelicopterParamsError(f'cannot read helicopter parameters {str(p)!r}: {exc.strerror}') from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        where = f' at line {mark.line + 1}' if mark is not None else ''
        raise HelicopterParamsError(f'YAML syntax error in {str(p)!r}{where}: '
                                    f'{getattr(exc, "problem", exc)}') from None
    if not isinstance(data, dict):
        raise HelicopterParamsError(f'{str(p)!r} must hold a mapping of helicopter parameters')
    names = [f.name for f in dataclasses.fields(HelicopterParams)]
    unknown = sorted(set(map(str, data)) - set(names))
    if unknown:
        raise HelicopterParamsError(f'{str(p)!r}: unknown key(s) {unknown}; allowed: {names}')
    missing = [n for n in names if n not in data]
    if missing:
        raise HelicopterParamsError(f'{str(p)!r}: missing key(s) {missing}')
    for name in _VECTOR_FIELDS:
        value = data[name]
        if not isinstance(value, list) or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            raise HelicopterParamsError(f'{str(p)!r}: {name!r} must be a list of numbers, got {value!r}')
    return HelicopterParams(**{n: data[n] for n in names})


# ---------------------------------------------------------------------------------------------
# Kinematics


def rotation_matrix(euler) -> np.ndarray:
    """Body-to-inertial rotation ``R = Rz(psi) Ry(theta) Rx(phi)`` (3, 3) for ``euler`` (3,) rad."""
    phi, th, psi = float(euler[0]), float(euler[1]), float(euler[2])
    cf, sf = math.cos(phi), math.sin(phi)
    ct, st = math.cos(th), math.sin(th)
    cp, sp = math.cos(psi), math.sin(psi)
    return np.array([
        [cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf],
        [sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf],
        [-st, ct * sf, ct * cf],
    ])


def euler_rate_matrix(euler) -> np.ndarray:
    """``H(Theta)`` (3, 3) with ``Theta' = H omega`` for ZYX Euler angles (DESIGN.md 2).

    Singular at ``theta = +-pi/2`` (gimbal lock), far outside the flight envelope.
    """
    phi, th = float(euler[0]), float(euler[1])
    cf, sf = math.cos(phi), math.sin(phi)
    ct, tt = math.cos(th), math.tan(th)
    return np.array([
        [1.0, sf * tt, cf * tt],
        [0.0, cf, -sf],
        [0.0, sf / ct, cf / ct],
    ])


# ---------------------------------------------------------------------------------------------
# Forces and moments


def clip_inputs(params: HelicopterParams, u) -> np.ndarray:
    """Inputs ``u`` (4,) rad limited to ``[input_lower, input_upper]`` (new array)."""
    return np.minimum(np.maximum(np.asarray(u, dtype=float), params.input_lower), params.input_upper)


def thrust(params: HelicopterParams, theta_col: float) -> float:
    """Main-rotor thrust ``T_M = c_M1 theta_col + c_M2``, N, for collective ``theta_col`` rad."""
    return params.c_M1 * float(theta_col) + params.c_M2


def rotor_moments(params: HelicopterParams, omega, u) -> np.ndarray:
    """Moment vector ``Gamma(omega, u)`` (3,) N m in the body frame (DESIGN.md 2.1)."""
    p, q, r = (float(v) for v in omega)
    T = params.c_M1 * float(u[0]) + params.c_M2
    k = params.K_beta + T * params.h_M
    return np.array([
        k * (params.B_lat * float(u[2]) - params.tau_f * p),
        k * (params.A_lon * float(u[3]) - params.tau_f * q),
        params.K_tr * float(u[1]) - params.D_r * r - params.c_Q * T,
    ])


def hover_trim(params: HelicopterParams, yaw: float = 0.0) -> np.ndarray:
    """Inputs (4,) rad that hold a level hover at rest with heading ``yaw`` rad.

    ``T_M = m g`` gives ``theta_col = (m g - c_M2) / c_M1``; zero yaw moment gives
    ``theta_tr = c_Q m g / K_tr``; zero cyclics. The heading does not change the trim (the
    model is symmetric in yaw); the argument exists for callers that trim at a heading.
    """
    del yaw
    mg = params.mass * params.gravity
    return np.array([(mg - params.c_M2) / params.c_M1, params.c_Q * mg / params.K_tr, 0.0, 0.0])


def _vector(values, size: int, what: str) -> np.ndarray:
    """``values`` as a fresh C-contiguous float64 array of shape (size,) (ValueError otherwise)."""
    arr = np.array(values, dtype=float).reshape(-1)
    if arr.shape != (size,):
        raise ValueError(f'{what} must have {size} elements, got shape {np.shape(values)}')
    return arr


def state_derivative(params: HelicopterParams, x, u_actual, force_disturbance=None) -> np.ndarray:
    """State derivative ``x'`` (12,) of DESIGN.md 2.1 (kernel :func:`.plant_kernels.state_derivative`).

    Parameters
    ----------
    params : HelicopterParams
    x : array_like (12,)
        State ``[p m, v m/s, Theta rad, omega rad/s]``.
    u_actual : array_like (4,)
        Inputs acting on the airframe (after faults and limits), rad. Not limited here.
    force_disturbance : array_like (3,), optional
        ``d_p`` N, inertial frame; zero when ``None``.

    Returns
    -------
    ndarray (12,)
        ``[v, v', Theta', omega']`` in m/s, m/s^2, rad/s, rad/s^2.
    """
    d = np.zeros(3) if force_disturbance is None else _vector(force_disturbance, 3, 'force_disturbance')
    out = np.empty(STATE_SIZE)
    _k.state_derivative(_vector(x, STATE_SIZE, 'state x'), _vector(u_actual, INPUT_SIZE, 'u_actual'), d,
                        _k.params_vector(params), out)
    return out


def lumped_faults(params: HelicopterParams, x, u_cmd, u_actual) -> tuple:
    """True lumped faults ``(F_p (3,) m/s^2 inertial, F_w (3,) rad/s^2 body)`` of DESIGN.md 2.2.

    ``u_cmd`` are the commanded inputs after the limits, ``u_actual`` the inputs after faults and
    limits, both (4,) rad; ``x`` (12,) the state at which they are evaluated
    (kernel :func:`.plant_kernels.lumped_faults_of_inputs`).
    """
    f_p, f_w = np.empty(3), np.empty(3)
    _k.lumped_faults_of_inputs(_vector(x, STATE_SIZE, 'state x'), _vector(u_cmd, INPUT_SIZE, 'u_cmd'),
                               _vector(u_actual, INPUT_SIZE, 'u_actual'), _k.params_vector(params), f_p, f_w)
    return f_p, f_w


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
    disturbance : SinusoidalDisturbance or callable, optional
        ``t -> d_p(t)`` force, 3 floats N, inertial frame. A :class:`SinusoidalDisturbance` runs in
        the kernels; any other callable is sampled in Python at the RK4 stage times (slower, and
        not available to njit callers, see :meth:`kernel_arrays`).

    Raises
    ------
    ValueError
        ``substeps`` not an int >= 1, a state that is not 12 finite numbers, or a disturbance that
        is neither ``None`` nor callable.
    FaultError
        ``faults`` not a :class:`FaultSchedule`.
    """

    def __init__(self, params: HelicopterParams, faults: FaultSchedule | None = None, x0=None,
                 substeps: int = 5, disturbance: Callable | None = None):
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
        """The kernel fault table, rebuilt when the schedule changed since it was built."""
        if self._faults.revision != self._fault_revision:
            self._fault_table = _k.fault_table(self._faults)
            self._fault_revision = self._faults.revision
        return self._fault_table

    @property
    def disturbance(self):
        """The force disturbance ``t -> d_p(t)`` N (``None``: no force)."""
        return self._disturbance

    @disturbance.setter
    def disturbance(self, disturbance) -> None:
        if disturbance is not None and not callable(disturbance):
            raise ValueError(f'disturbance must be a SinusoidalDisturbance, a callable t -> 3 floats N '
                             f'or None, got {type(disturbance).__name__}')
        self._disturbance = disturbance
        sinusoid = disturbance is None or isinstance(disturbance, SinusoidalDisturbance)
        self._sampled = not sinusoid
        self._dist_table = _k.disturbance_table(disturbance if sinusoid else None)

    def kernel_arrays(self) -> _k.PlantArrays:
        """Copies of the arrays the kernels take for this plant (see :mod:`.plant_kernels`).

        Raises
        ------
        ValueError
            When the disturbance is an arbitrary Python callable (not a
            :class:`SinusoidalDisturbance`), which njit code cannot evaluate.
        """
        if self._sampled:
            raise ValueError(f'kernel_arrays: the disturbance {self._disturbance!r} is a Python callable, '
                             f'not a SinusoidalDisturbance; only plant_step_sampled can use it')
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
        """``u_cmd`` as a writable C-contiguous float64 (4,) array (no copy when it already is one;
        a read-only array would make numba compile another specialisation of every kernel)."""
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
        """Inputs (4,) rad acting at time ``t`` s: limits, faults (eq. 6), limits again."""
        return self._inputs(u_cmd, t)[1]

    def fault_active(self, t: float) -> bool:
        """True when any fault channel is past its onset at ``t`` s."""
        return self._faults.active(t)

    def stuck(self, t: float) -> bool:
        """True when an active channel is stuck (``rho = 0``, not compensable)."""
        return self._faults.stuck(t)

    def _force(self, t: float) -> np.ndarray:
        """Force disturbance (3,) N at ``t`` s."""
        out = np.empty(3)
        if self._sampled:
            out[:] = self._disturbance(t)
        else:
            _k.force_disturbance(self._dist_table, t, out)
        return out

    def lumped_faults(self, u_cmd, t: float) -> tuple:
        """True lumped faults ``(F_p (3,) m/s^2 inertial, F_w (3,) rad/s^2 body)`` at the current
        state and time ``t`` s (DESIGN.md 2.2); exactly zero when no fault acts.

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
        u = self._command(u_cmd)
        t, dt = float(t), float(dt)
        if self._sampled:
            times = _k.disturbance_sample_times(t, dt, self.substeps)
            samples = np.array([self._disturbance(tt) for tt in times], dtype=float).reshape(len(times), 3)
            _k.plant_step_sampled(self._x, u, t, dt, self.substeps, self._params_vec, self._fault_array(),
                                  samples)
        else:
            _k.plant_step(self._x, u, t, dt, self.substeps, self._params_vec, self._fault_array(),
                          self._dist_table)
        return self._x.copy()


def plant_from_scenario(scenario, uh_id: int, params: HelicopterParams | None = None) -> HelicopterPlant:
    """The plant of UH ``uh_id`` of a ``uh_topology`` ``Scenario``: its initial state, faults,
    disturbance and substeps; ``params`` default to the scenario's helicopter file."""
    if params is None:
        params = load_helicopter_params(scenario.helicopter)
    return HelicopterPlant(
        params,
        FaultSchedule.from_specs(scenario.faults.get(uh_id, ())),
        scenario.initial_states[uh_id],
        substeps=scenario.substeps,
        disturbance=disturbance_from_spec(scenario.disturbance, uh_id),
    )
