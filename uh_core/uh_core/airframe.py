"""Airframe parameters of one helicopter: the physical constants and input limits (docs/model.md).

Both sides read them: the simulator integrates the true airframe, and the controller derives its
nominal model from the same record (``uh_controller_node.nominal_model``). The bundled file is
``uh_core/config/helicopter.yaml``; a scenario names the file its team uses.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from .checks import finite_real
from .layout import INPUT_NAMES, INPUT_SIZE

__all__ = ['HelicopterParamsError', 'HelicopterParams', 'load_helicopter_params', 'default_params_path']

_CONFIG_DIR = Path(__file__).resolve().parent / 'config'

_SCALAR_FIELDS = ('mass', 'gravity', 'c_M1', 'c_M2', 'K_beta', 'h_M', 'B_lat', 'A_lon', 'tau_f',
                  'K_tr', 'D_r', 'c_Q', 'D_v', 'rotor_radius')
_POSITIVE_FIELDS = ('mass', 'gravity', 'c_M1', 'K_beta', 'B_lat', 'A_lon', 'K_tr', 'rotor_radius')
_NONNEGATIVE_FIELDS = ('h_M', 'tau_f', 'D_r', 'c_Q', 'D_v')
_VECTOR_FIELDS = {'inertia': 3, 'input_lower': INPUT_SIZE, 'input_upper': INPUT_SIZE}


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
    """Physical parameters and input limits of one helicopter (docs/model.md, "Parameters").

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
    rotor_radius : float
        Main-rotor radius, hub to blade tip, m: two hubs closer than twice it overlap their rotor
        disks (docs/safety.md).
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
    rotor_radius: float
    input_lower: np.ndarray
    input_upper: np.ndarray

    def __post_init__(self):
        for name in _SCALAR_FIELDS:
            value = finite_real(getattr(self, name), f'helicopter parameter {name!r}', HelicopterParamsError)
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
            bad = [INPUT_NAMES[i] for i in range(INPUT_SIZE) if self.input_lower[i] >= self.input_upper[i]]
            raise HelicopterParamsError(f'input limits must satisfy input_lower < input_upper; '
                                        f'violated for {bad}')

    def as_dict(self) -> dict:
        """Plain mapping (floats and lists) with the YAML keys."""
        out = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            out[f.name] = value.tolist() if isinstance(value, np.ndarray) else value
        return out


def default_params_path() -> Path:
    """Path of the bundled ``uh_core/config/helicopter.yaml``."""
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
        A YAML file, or a bare name of a bundled file in ``uh_core/config`` (``'helicopter'``).
        Default: the bundled ``helicopter.yaml``. The file holds one mapping with exactly the
        fields of :class:`HelicopterParams` (numbers; ``inertia`` 3 numbers; limits 4 numbers).

    Raises
    ------
    HelicopterParamsError
        Missing file, YAML syntax error, unknown or missing key, wrong type or value.
    """
    p = _resolve_params_path(path)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise HelicopterParamsError(f'cannot read helicopter parameters {str(p)!r}: {exc.strerror}') from None
    try:
        text = raw.decode('utf-8')
    except UnicodeDecodeError as exc:
        line = raw.count(b'\n', 0, exc.start) + 1
        raise HelicopterParamsError(f'{p}:{line}: not UTF-8 text: byte 0x{raw[exc.start]:02x} at offset '
                                    f'{exc.start}; allowed: a YAML text file in UTF-8') from None
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
