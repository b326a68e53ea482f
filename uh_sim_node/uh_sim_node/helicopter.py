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
The core works on Python floats (no per-stage numpy allocation) because the team simulation calls
it several hundred thousand times per scenario.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import yaml

from .faults import ONSET_TOLERANCE, FaultSchedule

__all__ = [
    'INPUT_NAMES', 'STATE_SIZE', 'INPUT_SIZE', 'HelicopterParamsError', 'HelicopterParams',
    'load_helicopter_params', 'default_params_path', 'rotation_matrix', 'euler_rate_matrix',
    'clip_inputs', 'hover_trim', 'thrust', 'rotor_moments', 'state_derivative',
    'lumped_faults', 'SinusoidalDisturbance', 'disturbance_from_spec', 'HelicopterPlant',
    'plant_from_scenario',
]

#: Names of the four physical inputs, in channel order 0..3.
INPUT_NAMES = ('theta_col', 'theta_tr', 'delta_lat', 'delta_lon')
STATE_SIZE = 12
INPUT_SIZE = 4

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


def _make_rates(params: HelicopterParams):
    """Closure ``f(vx, vy, vz, phi, theta, psi, p, q, r, u0, u1, u2, u3, dx, dy, dz)`` on floats.

    Returns the 9 derivatives ``(v', Theta', omega')`` of DESIGN.md 2.1 (``p' = v`` is handled by
    the caller). Constants live in the closure so that a call does no lookups or allocations
    besides the result tuple.
    """
    cos, sin = math.cos, math.sin
    m, g, dv = params.mass, params.gravity, params.D_v
    cm1, cm2, kb, hm = params.c_M1, params.c_M2, params.K_beta, params.h_M
    blat, alon, tauf = params.B_lat, params.A_lon, params.tau_f
    ktr, dr, cq = params.K_tr, params.D_r, params.c_Q
    jx, jy, jz = (float(v) for v in params.inertia)
    im, ijx, ijy, ijz = 1.0 / m, 1.0 / jx, 1.0 / jy, 1.0 / jz
    jyz, jzx, jxy = jy - jz, jz - jx, jx - jy

    def rates(vx, vy, vz, phi, th, psi, p, q, r, u0, u1, u2, u3, dx, dy, dz):
        cf = cos(phi)
        sf = sin(phi)
        ct = cos(th)
        st = sin(th)
        cp = cos(psi)
        sp = sin(psi)
        T = cm1 * u0 + cm2                 # main-rotor thrust, N
        tm = T * im
        stcf = st * cf
        qs = sf * q + cf * r
        k = kb + T * hm                    # flapping moment stiffness, N m/rad
        return (
            # m v' = T R e3 - D_v v + d_p - m g e3, with R e3 the third column of R
            tm * (cp * stcf + sp * sf) + (dx - dv * vx) * im,
            tm * (sp * stcf - cp * sf) + (dy - dv * vy) * im,
            tm * ct * cf + (dz - dv * vz) * im - g,
            # Theta' = H omega
            p + st / ct * qs,
            cf * q - sf * r,
            qs / ct,
            # J omega' = -omega x J omega + Gamma, J diagonal; flapping b_1s, a_1s inline
            (jyz * q * r + k * (blat * u2 - tauf * p)) * ijx,
            (jzx * r * p + k * (alon * u3 - tauf * q)) * ijy,
            (jxy * p * q + ktr * u1 - dr * r - cq * T) * ijz,
        )

    return rates


def _rk4_substep(f, x, h, ua, ub, uc, d0, d1, d2):
    """One classical RK4 step of length ``h`` on the 12 floats ``x``.

    ``ua``/``d0`` act at the start, ``ub``/``d1`` at the midpoint, ``uc``/``d2`` at the end.
    """
    h2 = 0.5 * h
    x0, x1, x2, x3, x4, x5, x6, x7, x8, x9, x10, x11 = x
    a = f(x3, x4, x5, x6, x7, x8, x9, x10, x11, ua[0], ua[1], ua[2], ua[3], d0[0], d0[1], d0[2])
    b = f(x3 + h2 * a[0], x4 + h2 * a[1], x5 + h2 * a[2], x6 + h2 * a[3], x7 + h2 * a[4],
          x8 + h2 * a[5], x9 + h2 * a[6], x10 + h2 * a[7], x11 + h2 * a[8],
          ub[0], ub[1], ub[2], ub[3], d1[0], d1[1], d1[2])
    c = f(x3 + h2 * b[0], x4 + h2 * b[1], x5 + h2 * b[2], x6 + h2 * b[3], x7 + h2 * b[4],
          x8 + h2 * b[5], x9 + h2 * b[6], x10 + h2 * b[7], x11 + h2 * b[8],
          ub[0], ub[1], ub[2], ub[3], d1[0], d1[1], d1[2])
    d = f(x3 + h * c[0], x4 + h * c[1], x5 + h * c[2], x6 + h * c[3], x7 + h * c[4],
          x8 + h * c[5], x9 + h * c[6], x10 + h * c[7], x11 + h * c[8],
          uc[0], uc[1], uc[2], uc[3], d2[0], d2[1], d2[2])
    h6 = h / 6.0
    # p' = v: the stage velocities are v, v + h/2 a_v, v + h/2 b_v, v + h c_v, so
    # (k1 + 2 k2 + 2 k3 + k4)_p = 6 v + h (a_v + b_v + c_v).
    return (
        x0 + h6 * (6.0 * x3 + h * (a[0] + b[0] + c[0])),
        x1 + h6 * (6.0 * x4 + h * (a[1] + b[1] + c[1])),
        x2 + h6 * (6.0 * x5 + h * (a[2] + b[2] + c[2])),
        x3 + h6 * (a[0] + 2.0 * b[0] + 2.0 * c[0] + d[0]),
        x4 + h6 * (a[1] + 2.0 * b[1] + 2.0 * c[1] + d[1]),
        x5 + h6 * (a[2] + 2.0 * b[2] + 2.0 * c[2] + d[2]),
        x6 + h6 * (a[3] + 2.0 * b[3] + 2.0 * c[3] + d[3]),
        x7 + h6 * (a[4] + 2.0 * b[4] + 2.0 * c[4] + d[4]),
        x8 + h6 * (a[5] + 2.0 * b[5] + 2.0 * c[5] + d[5]),
        x9 + h6 * (a[6] + 2.0 * b[6] + 2.0 * c[6] + d[6]),
        x10 + h6 * (a[7] + 2.0 * b[7] + 2.0 * c[7] + d[7]),
        x11 + h6 * (a[8] + 2.0 * b[8] + 2.0 * c[8] + d[8]),
    )


def state_derivative(params: HelicopterParams, x, u_actual, force_disturbance=None) -> np.ndarray:
    """State derivative ``x'`` (12,) of DESIGN.md 2.1.

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
    xs = [float(v) for v in np.asarray(x, dtype=float).reshape(STATE_SIZE)]
    u = [float(v) for v in np.asarray(u_actual, dtype=float).reshape(INPUT_SIZE)]
    d = (0.0, 0.0, 0.0) if force_disturbance is None else [float(v) for v in force_disturbance]
    rates = _make_rates(params)(*xs[3:], u[0], u[1], u[2], u[3], d[0], d[1], d[2])
    return np.array(xs[3:6] + list(rates))


def lumped_faults(params: HelicopterParams, x, u_cmd, u_actual) -> tuple:
    """True lumped faults ``(F_p (3,) m/s^2 inertial, F_w (3,) rad/s^2 body)`` of DESIGN.md 2.2.

    ``u_cmd`` are the commanded inputs after the limits, ``u_actual`` the inputs after faults and
    limits, both (4,) rad; ``x`` (12,) the state at which they are evaluated.
    """
    x = np.asarray(x, dtype=float)
    R = rotation_matrix(x[6:9])
    t_act = thrust(params, u_actual[0])
    t_cmd = thrust(params, u_cmd[0])
    f_p = (t_act - t_cmd) / params.mass * R[:, 2]
    f_w = (rotor_moments(params, x[9:12], u_actual) - rotor_moments(params, x[9:12], u_cmd)) / params.inertia
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

    Calling the object with time ``t`` s returns a tuple of 3 floats (N).
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

    Parameters
    ----------
    params : HelicopterParams
        True parameters of this airframe.
    faults : FaultSchedule, optional
        Actuator faults (none when ``None``). The schedule object is kept, so faults added to it
        later (fault injection) act from then on.
    x0 : array_like (12,), optional
        Initial state (default: origin, at rest, level).
    substeps : int
        RK4 substeps per control period (>= 1).
    disturbance : callable, optional
        ``t -> d_p(t)`` force, 3 floats N, inertial frame.
    """

    def __init__(self, params: HelicopterParams, faults: FaultSchedule | None = None, x0=None,
                 substeps: int = 5, disturbance: Callable | None = None):
        if isinstance(substeps, bool) or not isinstance(substeps, (int, np.integer)) or substeps < 1:
            raise ValueError(f'substeps must be an int >= 1, got {substeps!r}')
        self.params = params
        self.faults = faults if faults is not None else FaultSchedule()
        self.substeps = int(substeps)
        self.disturbance = disturbance
        self._rates = _make_rates(params)
        self._inertia = tuple(float(v) for v in params.inertia)
        self._lo = tuple(float(v) for v in params.input_lower)
        self._hi = tuple(float(v) for v in params.input_upper)
        self.reset(np.zeros(STATE_SIZE) if x0 is None else x0)

    # -- state ------------------------------------------------------------------------------
    def reset(self, x0) -> None:
        """Set the state to ``x0`` (12,)."""
        arr = np.array(x0, dtype=float).reshape(-1)
        if arr.shape != (STATE_SIZE,) or not np.all(np.isfinite(arr)):
            raise ValueError(f'helicopter state must be 12 finite numbers, got {np.shape(x0)}')
        self._x = tuple(float(v) for v in arr)

    @property
    def x(self) -> np.ndarray:
        """Current state (12,) float64 (a fresh array)."""
        return np.array(self._x)

    # -- inputs -----------------------------------------------------------------------------
    def _clip(self, u0, u1, u2, u3):
        lo, hi = self._lo, self._hi
        return (min(max(u0, lo[0]), hi[0]), min(max(u1, lo[1]), hi[1]),
                min(max(u2, lo[2]), hi[2]), min(max(u3, lo[3]), hi[3]))

    def _actual(self, uc, t, t_switch):
        """Faulted and re-limited inputs (4 floats) for limited command ``uc`` at time ``t``; the
        faults' activity is decided at ``t_switch`` (the substep start, see :mod:`.faults`)."""
        faults = self.faults.faults
        if not faults:
            return uc
        u = list(uc)
        lo, hi = self._lo, self._hi
        for f in faults:
            if t_switch >= f.onset_time - ONSET_TOLERANCE:
                ch = f.channel
                # eq. 6, then the physical travel limits of that actuator again
                u[ch] = min(max(f.apply(u[ch], t), lo[ch]), hi[ch])
        return u

    def _disturbance_function(self):
        """``t -> (3 floats)``: the sinusoidal disturbance's own evaluation, else a float wrapper."""
        d = self.disturbance
        if isinstance(d, SinusoidalDisturbance):
            return d
        return self._disturb

    def _disturb(self, t):
        d = self.disturbance
        if d is None:
            return (0.0, 0.0, 0.0)
        f = d(t)
        return (float(f[0]), float(f[1]), float(f[2]))

    def commanded_inputs(self, u_cmd) -> np.ndarray:
        """``u_cmd`` (4,) rad after the input limits."""
        return np.array(self._clip(*(float(v) for v in u_cmd)))

    def actual_inputs(self, u_cmd, t: float) -> np.ndarray:
        """Inputs (4,) rad acting at time ``t`` s: limits, faults (eq. 6), limits again."""
        uc = self._clip(*(float(v) for v in u_cmd))
        return np.array(self._actual(uc, float(t), float(t)))

    def fault_active(self, t: float) -> bool:
        """True when any fault channel is past its onset at ``t`` s."""
        return self.faults.active(t)

    def stuck(self, t: float) -> bool:
        """True when an active channel is stuck (``rho = 0``, not compensable)."""
        return self.faults.stuck(t)

    def lumped_faults(self, u_cmd, t: float) -> tuple:
        """True lumped faults ``(F_p (3,), F_w (3,))`` at the current state and time ``t`` s.

        ``u_cmd`` is the controller's command (4,) rad; it is limited first (DESIGN.md 2.2).
        """
        uc = self._clip(*(float(v) for v in u_cmd))
        ua = self._actual(uc, float(t), float(t))
        if ua is uc:  # no fault: exactly zero
            return np.zeros(3), np.zeros(3)
        # scalar form of lumped_faults() (same formulas; this runs once per step per UH)
        prm = self.params
        phi, th, psi, p, q, r = self._x[6:12]
        cf, sf, ct, st = math.cos(phi), math.sin(phi), math.cos(th), math.sin(th)
        cp, sp = math.cos(psi), math.sin(psi)
        t_act = prm.c_M1 * ua[0] + prm.c_M2
        t_cmd = prm.c_M1 * uc[0] + prm.c_M2
        g = (t_act - t_cmd) / prm.mass
        f_p = np.array([g * (cp * st * cf + sp * sf), g * (sp * st * cf - cp * sf), g * ct * cf])
        k_act = prm.K_beta + t_act * prm.h_M
        k_cmd = prm.K_beta + t_cmd * prm.h_M
        jx, jy, jz = self._inertia
        f_w = np.array([
            (k_act * (prm.B_lat * ua[2] - prm.tau_f * p) - k_cmd * (prm.B_lat * uc[2] - prm.tau_f * p)) / jx,
            (k_act * (prm.A_lon * ua[3] - prm.tau_f * q) - k_cmd * (prm.A_lon * uc[3] - prm.tau_f * q)) / jy,
            ((prm.K_tr * ua[1] - prm.D_r * r - prm.c_Q * t_act)
             - (prm.K_tr * uc[1] - prm.D_r * r - prm.c_Q * t_cmd)) / jz,
        ])
        return f_p, f_w

    def derivative(self, u_cmd, t: float) -> np.ndarray:
        """State derivative (12,) at the current state for command ``u_cmd`` at time ``t``."""
        uc = self._clip(*(float(v) for v in u_cmd))
        ua = self._actual(uc, float(t), float(t))
        d = self._disturb(float(t))
        x = self._x
        return np.array(x[3:6] + self._rates(*x[3:], ua[0], ua[1], ua[2], ua[3], d[0], d[1], d[2]))

    # -- integration ------------------------------------------------------------------------
    def step(self, u_cmd, t: float, dt: float) -> np.ndarray:
        """Advance from ``t`` to ``t + dt`` s holding ``u_cmd`` (4,) rad; returns the new state (12,).

        ``u_cmd`` is limited, then faults and limits are applied at each RK4 stage time.
        """
        uc = self._clip(*(float(v) for v in u_cmd))
        t = float(t)
        n = self.substeps
        h = float(dt) / n
        f = self._rates
        x = self._x
        faulty = bool(self.faults.faults)
        dist = self.disturbance is not None
        zero = (0.0, 0.0, 0.0)
        # Substep s spans [t + s h, t + (s + 1) h]. The faults' activity is decided at its start
        # (a fault switches on at a substep boundary, see uh_sim_node.faults); the bias and the
        # disturbance are evaluated at the stage times. The end value of a substep is reused as the
        # start value of the next when the activity has not changed (same float time).
        u_mid, u_end, d_mid, d_end = uc, uc, zero, zero
        u_start = self._actual(uc, t, t) if faulty else uc
        disturb = self._disturbance_function()
        d_start = disturb(t) if dist else zero
        # Does a fault switch on inside this control period? If not, the set of acting faults is
        # constant, the constant-bias channels are evaluated once and only the sinusoidal biases
        # are re-evaluated at the stage times (same arithmetic as _actual, faster).
        switching = faulty and any(t < f.onset_time - ONSET_TOLERANCE <= t + float(dt)
                                   for f in self.faults.faults)
        sinusoids = ()
        if faulty and not switching:
            lo, hi = self._lo, self._hi
            sinusoids = tuple((f.channel, f.rho * uc[f.channel] + f.bias_constant, f.bias_amplitude,
                               f.bias_frequency, lo[f.channel], hi[f.channel])
                              for f in self.faults.faults
                              if f.bias_amplitude != 0.0 and f.started(t))
            u_mid = u_end = u_start
        sin = math.sin
        for s in range(n):
            t_start = t + s * h
            t_mid = t + (s + 0.5) * h
            t_end = t + (s + 1) * h
            if switching:
                if s > 0:
                    u_start = self._actual(uc, t_start, t_start)
                u_mid = self._actual(uc, t_mid, t_start)
                u_end = self._actual(uc, t_end, t_start)
            elif sinusoids:
                u_start = u_end if s > 0 else u_start
                u_mid = list(u_start)
                u_end = list(u_start)
                for ch, base, amp, freq, lo_c, hi_c in sinusoids:
                    u_mid[ch] = min(max(base + amp * sin(freq * t_mid), lo_c), hi_c)
                    u_end[ch] = min(max(base + amp * sin(freq * t_end), lo_c), hi_c)
            if dist:
                d_mid = disturb(t_mid)
                d_end = disturb(t_end)
            x = _rk4_substep(f, x, h, u_start, u_mid, u_end, d_start, d_mid, d_end)
            d_start = d_end
        self._x = x
        return np.array(x)


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
