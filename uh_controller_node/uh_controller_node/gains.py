"""Gains of the composite-learning inverse-optimal fault-tolerant controller (docs/control_law.md).

The gains of one scenario live in one YAML file (``uh_topology/config/paper_gains.yaml`` for the
paper scenario), either as a plain mapping or keyed ``/**: ros__parameters:`` like a ROS 2
parameter file::

    /**:
      ros__parameters:
        beta: 2.0
        tilt_limit_deg: 30.0
        min_vertical_accel: 2.0
        outer: {k: ..., r: ..., tau_command: ..., kappa: ..., ...}
        inner: {k: ..., r: ..., tau_command: ..., tau_rate: ..., kappa: ..., ...}

The comparison cases of docs/control_law.md#comparison-cases are the same gains with exactly these changes:

* ``proposed``: as written;
* ``case1`` (non-optimal law): ``beta = 1`` (violates Lemma 2's ``beta >= 2``);
* ``case2`` (no serial-parallel estimation model): ``gamma = gamma_F = 0`` and ``kappa = 0`` in
  both loops, so the learning laws are driven by the tracking errors alone.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from uh_topology.errors import ScenarioError
from uh_topology.schema import parse_yaml

__all__ = ['CASES', 'GainsError', 'gains_source', 'scenario_gains', 'located',
           'RBFSpec', 'LoopGains', 'ControllerGains', 'GainParameter',
           'gain_parameters', 'nest_gains']

#: The comparison cases of docs/control_law.md#comparison-cases, in report order.
CASES = ('proposed', 'case1', 'case2')


class GainsError(ScenarioError):
    """Controller gains that cannot be used: an entry unknown, missing or invalid, or an unknown case.

    A scenario's error, like the ``GainsFileError`` of a gains file that cannot be read
    (``uh_topology.errors``), so a caller that loads a scenario and builds its controllers catches
    either as a ``ScenarioError``.

    ``keys`` is the key path of the entry at fault inside the gains mapping (e.g. ``('outer', 'k')``),
    empty when the error is not about one entry; :func:`scenario_gains` turns it into a line of the file.
    """

    def __init__(self, message: str, *, keys=()):
        self.keys = tuple(keys)
        super().__init__(message)


@dataclass(frozen=True)
class RBFSpec:
    """Gaussian RBF layer of one loop: ``nodes`` centres evenly spaced on ``[low, high]``.

    Attributes
    ----------
    nodes : int
        Number of centres per axis (mu), >= 1.
    low, high : float
        First and last centre (m/s outer, rad/s inner), ``low < high`` unless ``nodes == 1``.
    width : float
        Width b of ``S_i(x) = exp(-(x - c_i)^2 / b^2)`` (same unit as the centres), > 0.
    """

    nodes: int
    low: float
    high: float
    width: float


@dataclass(frozen=True)
class LoopGains:
    """Gains of one loop (outer: position/velocity, docs/control_law.md#outer-loop; inner: attitude/rate, 2.5).

    Attributes
    ----------
    k : float
        k1 (outer) or k3 (inner), 1/s: gain of the first backstepping error in the virtual control.
    r : float
        Inverse-optimal input weight r_p / r_w, s; feedback gain of z2 / z4 is ``beta / (2 r)`` 1/s.
    tau_command : float
        Time constant of the command filter of alpha_v (outer) or of Theta_d (inner), s.
    tau_rate : float or None
        Inner loop only: time constant of the filter of alpha_w, s (``None`` for the outer loop).
    kappa : float
        Gain of the serial-parallel estimation model (SPEM), 1/s.
    learning_rate : float
        Gamma of the network weights' update law, 1/s.
    gamma : float
        Weight of the prediction error in the weights' update law (-).
    gamma_F : float
        Weight of the prediction error in the fault observer (-).
    sigma : float
        Leakage (sigma-modification) of the network weights (-).
    lambda_ : float
        Gain lambda of the fault estimation observer, 1/s (YAML key ``lambda``).
    sigma_F : float
        Leakage of the fault estimate (-).
    fault_bound : float
        Projection radius of each component of Fhat: m/s^2 (outer), rad/s^2 (inner).
    weight_bound : float
        Projection radius of each column (axis) of W, Euclidean norm (m/s^2 or rad/s^2).
    rbf : RBFSpec
        Centres and width of the Gaussian basis.
    late_learning_rate, late_sigma : float
        Gamma (1/s) and sigma (-) of the weights after the learning phase
        (docs/control_law.md#learning-phase); YAML keys optional, default ``learning_rate`` and
        ``sigma`` (no change at the end of the phase).
    """

    k: float
    r: float
    tau_command: float
    tau_rate: float | None
    kappa: float
    learning_rate: float
    gamma: float
    gamma_F: float
    sigma: float
    lambda_: float
    sigma_F: float
    fault_bound: float
    weight_bound: float
    rbf: RBFSpec
    late_learning_rate: float
    late_sigma: float


@dataclass(frozen=True)
class ControllerGains:
    """All gains of one UH controller for one comparison case (docs/control_law.md).

    Attributes
    ----------
    case : str
        One of :data:`CASES`.
    beta : float
        Inverse-optimal factor (-); Lemma 2 requires ``beta >= 2`` (``case1`` sets 1).
    tilt_limit : float
        Largest tilt of the thrust vector from vertical, rad (Assumption 3).
    min_vertical_accel : float
        Smallest vertical specific thrust demanded, m/s^2 (keeps the thrust pointing up).
    outer, inner : LoopGains
        Gains of the position and attitude loops.
    learning_phase : float
        Simulated seconds after the first step during which the networks learn what the nominal
        model misses and the fault observers hold their estimates at zero
        (docs/control_law.md#learning-phase); YAML key optional, default 0 (no phase).
    """

    case: str
    beta: float
    tilt_limit: float
    min_vertical_accel: float
    outer: LoopGains
    inner: LoopGains
    learning_phase: float = 0.0

    @classmethod
    def from_mapping(cls, mapping, case: str = 'proposed', source: str = 'gains') -> 'ControllerGains':
        """Build the gains of ``case`` from a gains mapping (see module docstring).

        Parameters
        ----------
        mapping : dict
            Plain mapping or ``{'/**': {'ros__parameters': {...}}}``.
        case : str
            ``'proposed'``, ``'case1'`` or ``'case2'`` (docs/control_law.md#comparison-cases).
        source : str
            Where the mapping came from, used in error messages.

        Raises
        ------
        GainsError
            Unknown case; mapping not a dict; unknown or missing key; value not a finite number
            of the allowed range.
        """
        if case not in CASES:
            raise GainsError(f'unknown controller case {case!r}; allowed: {", ".join(CASES)}')
        data = _unwrap(mapping, source)
        _check_keys(data, _TOP_KEYS, source, optional=('learning_phase',))
        beta = _number(data, 'beta', source, minimum=0.0, strict=True)
        tilt_deg = _number(data, 'tilt_limit_deg', source, minimum=0.0, strict=True)
        if tilt_deg >= 90.0:
            raise GainsError(f'{source}: tilt_limit_deg must be < 90, got {tilt_deg!r}', keys=('tilt_limit_deg',))
        gains = cls(
            case='proposed',
            beta=beta,
            tilt_limit=math.radians(tilt_deg),
            min_vertical_accel=_number(data, 'min_vertical_accel', source, minimum=0.0, strict=True),
            outer=_loop(data, 'outer', source),
            inner=_loop(data, 'inner', source),
            learning_phase=(_number(data, 'learning_phase', source, minimum=0.0)
                            if 'learning_phase' in data else 0.0),
        )
        return gains.for_case(case)

    def for_case(self, case: str) -> 'ControllerGains':
        """Give these gains with the changes of comparison case ``case`` (docs/control_law.md#comparison-cases).

        ``case1``: ``beta = 1``. ``case2``: ``gamma = gamma_F = kappa = 0`` in both loops.
        Nothing else differs. Applied to the proposed gains only (a case is not stacked on another).
        """
        if case not in CASES:
            raise GainsError(f'unknown controller case {case!r}; allowed: {", ".join(CASES)}')
        if self.case != 'proposed':
            raise GainsError(f'case {case!r} must be derived from the proposed gains, not from {self.case!r}')
        if case == 'proposed':
            return self
        if case == 'case1':
            return dataclasses.replace(self, case=case, beta=1.0)
        no_spem = dict(gamma=0.0, gamma_F=0.0, kappa=0.0)
        return dataclasses.replace(self, case=case,
                                   outer=dataclasses.replace(self.outer, **no_spem),
                                   inner=dataclasses.replace(self.inner, **no_spem))


_TOP_KEYS = ('beta', 'tilt_limit_deg', 'min_vertical_accel', 'outer', 'inner')
_LOOP_KEYS = ('k', 'r', 'tau_command', 'kappa', 'learning_rate', 'gamma', 'gamma_F',
              'sigma', 'lambda', 'sigma_F', 'fault_bound', 'weight_bound', 'rbf_nodes', 'rbf_low',
              'rbf_high', 'rbf_width')
# key -> strictly positive (True) or non-negative (False)
_LOOP_POSITIVE = {'k': True, 'r': True, 'tau_command': True, 'tau_rate': True, 'kappa': False,
                  'learning_rate': False, 'gamma': False, 'gamma_F': False, 'sigma': False,
                  'lambda': False, 'sigma_F': False, 'fault_bound': True, 'weight_bound': True,
                  'rbf_width': True, 'late_learning_rate': False, 'late_sigma': False}
#: optional loop keys: the weights' law after the learning phase (default: unchanged)
_LOOP_LATE = ('late_learning_rate', 'late_sigma')


def _unwrap(mapping, source):
    if not isinstance(mapping, dict):
        raise GainsError(f'{source}: gains must be a mapping, got {type(mapping).__name__}')
    if '/**' in mapping:
        if set(mapping) != {'/**'}:
            raise GainsError(f'{source}: a "/**" keyed gains file may hold only the "/**" key')
        inner = mapping['/**']
        if not isinstance(inner, dict) or set(inner) != {'ros__parameters'} \
                or not isinstance(inner['ros__parameters'], dict):
            raise GainsError(f'{source}: "/**" must hold exactly one mapping "ros__parameters"')
        return inner['ros__parameters']
    return mapping


def _check_keys(data, required, where, optional=(), keys=()):
    allowed = tuple(required) + tuple(optional)
    unknown = sorted(str(k) for k in data if k not in allowed)
    if unknown:
        raise GainsError(f'{where}: unknown key(s) {unknown}; allowed: {", ".join(allowed)}',
                         keys=keys + (unknown[0],))
    missing = [k for k in required if k not in data]
    if missing:
        raise GainsError(f'{where}: missing key(s) {missing}', keys=keys)


def _number(data, key, where, minimum=None, strict=False, keys=()):
    value = data[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise GainsError(f'{where}: {key} must be a number, got {value!r}', keys=keys + (key,))
    value = float(value)
    if not math.isfinite(value):
        raise GainsError(f'{where}: {key} must be finite, got {value!r}', keys=keys + (key,))
    if minimum is not None and (value < minimum or (strict and value == minimum)):
        relation = '>' if strict else '>='
        raise GainsError(f'{where}: {key} must be {relation} {minimum:g}, got {value!r}', keys=keys + (key,))
    return value


def _loop(data, name, source):
    where = f'{source}: {name}'
    loop = data[name]
    if not isinstance(loop, dict):
        raise GainsError(f'{where} must be a mapping of loop gains, got {type(loop).__name__}', keys=(name,))
    keys = _LOOP_KEYS + (('tau_rate',) if name == 'inner' else ())
    _check_keys(loop, keys, where, optional=_LOOP_LATE, keys=(name,))
    values = {key: _number(loop, key, where, minimum=0.0, strict=strict, keys=(name,))
              for key, strict in _LOOP_POSITIVE.items() if key in keys or key in loop}
    nodes = loop['rbf_nodes']
    if isinstance(nodes, bool) or not isinstance(nodes, int) or nodes < 1:
        raise GainsError(f'{where}: rbf_nodes must be an integer >= 1, got {nodes!r}', keys=(name, 'rbf_nodes'))
    low = _number(loop, 'rbf_low', where, keys=(name,))
    high = _number(loop, 'rbf_high', where, keys=(name,))
    if nodes > 1 and not low < high:
        raise GainsError(f'{where}: rbf_low must be < rbf_high, got {low!r} and {high!r}', keys=(name, 'rbf_low'))
    return LoopGains(
        k=values['k'], r=values['r'], tau_command=values['tau_command'], tau_rate=values.get('tau_rate'),
        kappa=values['kappa'], learning_rate=values['learning_rate'], gamma=values['gamma'],
        gamma_F=values['gamma_F'], sigma=values['sigma'], lambda_=values['lambda'],
        sigma_F=values['sigma_F'], fault_bound=values['fault_bound'],
        weight_bound=values['weight_bound'],
        rbf=RBFSpec(nodes=nodes, low=low, high=high, width=values['rbf_width']),
        late_learning_rate=values.get('late_learning_rate', values['learning_rate']),
        late_sigma=values.get('late_sigma', values['sigma']))


# -- the gains as ROS parameters (docs/control_law.md#gains-as-parameters) -------------------------
#: What each gain key means, with its unit (the parameter descriptions).
GAIN_DESCRIPTIONS = {
    'beta': 'inverse-optimal factor beta (-); Lemma 2 needs beta >= 2',
    'tilt_limit_deg': 'largest thrust tilt from vertical, deg (< 90)',
    'min_vertical_accel': 'smallest vertical specific thrust commanded, m/s^2',
    'learning_phase': 's after take-off in which the networks learn and the fault observers hold zero',
    'k': 'error gain (k1 outer, k3 inner), 1/s',
    'r': 'inverse-optimal input weight r, s',
    'tau_command': 'command filter time constant, s',
    'tau_rate': 'filter time constant of alpha_w, s',
    'kappa': 'SPEM correction gain, 1/s',
    'learning_rate': 'network learning rate Gamma, 1/s',
    'gamma': 'prediction-error weight in the weight law (-)',
    'gamma_F': 'prediction-error weight in the fault observer (-)',
    'sigma': 'weight leakage (-)',
    'lambda': 'fault observer gain, 1/s',
    'sigma_F': 'fault-estimate leakage (-)',
    'fault_bound': 'projection bound of each fault-estimate component',
    'weight_bound': 'projection bound of each weight column norm',
    'rbf_nodes': 'RBF centres per axis (-); fixed at start',
    'rbf_low': 'first RBF centre; fixed at start',
    'rbf_high': 'last RBF centre; fixed at start',
    'rbf_width': 'Gaussian width of the RBFs; fixed at start',
    'late_learning_rate': 'learning rate after the learning phase, 1/s',
    'late_sigma': 'weight leakage after the learning phase (-)',
}
#: Keys that size or place the networks: read-only once the controller runs.
STRUCTURAL_KEYS = ('rbf_nodes', 'rbf_low', 'rbf_high', 'rbf_width')


@dataclass(frozen=True)
class GainParameter:
    """One gain as a ROS parameter.

    ``name`` (``beta``, ``outer.k`` ...), default ``value``, ``description``, lower bound
    ``minimum`` (None: none) and ``read_only``.
    """

    name: str
    value: object
    description: str
    minimum: float | None
    read_only: bool


def gains_source(scenario) -> str:
    """How errors name a scenario's gains: the gains file, else ``gains of scenario '<name>'`` (inline gains)."""
    path = getattr(scenario, 'gains_path', None)
    return str(path) if path is not None else f'gains of scenario {getattr(scenario, "name", "?")!r}'


def located(exc: GainsError, scenario) -> GainsError:
    """Give ``exc`` with the line of its entry in the scenario's gains file (``<file>:<line>: ...``).

    ``exc`` itself when the gains are inline, the file cannot be read again or the entry has no line.
    """
    path = getattr(scenario, 'gains_path', None)
    source = gains_source(scenario)
    if path is None or not exc.keys or not str(exc).startswith(source + ':'):
        return exc
    try:
        _, lines = parse_yaml(path.read_text(), source)
    except (OSError, ScenarioError):
        return exc
    for prefix in ((), ('/**', 'ros__parameters')):
        keys = prefix + exc.keys
        while len(keys) > len(prefix) and keys not in lines:
            keys = keys[:-1]        # a missing key: the line of the mapping that lacks it
        if keys in lines and len(keys) > len(prefix):
            rest = str(exc)[len(source) + 1:]
            return GainsError(f'{source}:{lines[keys]}:{rest}', keys=exc.keys)
    return exc


def scenario_gains(scenario, case: str) -> 'ControllerGains':
    """Build the gains of ``case`` from a scenario's gains; an error names the gains file and the line."""
    try:
        return ControllerGains.from_mapping(scenario.gains, case, source=gains_source(scenario))
    except GainsError as exc:
        raise located(exc, scenario) from None


def gain_parameters(mapping, source: str = 'gains') -> list:
    """List the gains of ``mapping`` as :class:`GainParameter`, in file order.

    ``mapping`` is plain or ``/**: ros__parameters:``, validated as by
    :meth:`ControllerGains.from_mapping`; the loops' gains have dotted names (``outer.k``).
    """
    ControllerGains.from_mapping(mapping, 'proposed', source)   # validate first: clear errors
    data = _unwrap(mapping, source)
    out = []
    for key, value in data.items():
        if isinstance(value, dict):
            for sub, sub_value in value.items():
                out.append(_gain_parameter(f'{key}.{sub}', sub, sub_value))
        else:
            out.append(_gain_parameter(key, key, value))
    return out


def _gain_parameter(name, key, value):
    if key == 'rbf_nodes':
        return GainParameter(name, int(value), GAIN_DESCRIPTIONS[key], 1.0, True)
    minimum = None if key in ('rbf_low', 'rbf_high') else 0.0
    return GainParameter(name, float(value), GAIN_DESCRIPTIONS.get(key, key), minimum, key in STRUCTURAL_KEYS)


def nest_gains(flat: dict) -> dict:
    """``{'beta': 2.0, 'outer.k': 1.0, ...}`` -> the nested mapping of a gains file."""
    out = {}
    for name, value in flat.items():
        head, dot, tail = name.partition('.')
        if dot:
            out.setdefault(head, {})[tail] = value
        else:
            out[name] = value
    return out

