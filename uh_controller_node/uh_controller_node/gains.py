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

Every gain is declared once, in :data:`GAINS` (a :class:`Gain`: key, unit, allowed values,
meaning, slot in the kernels' parameter vector). From that table come the records
:class:`ControllerGains` and :class:`LoopGains`, the reader of the file (errors
``<file>:<line>: <loop>: <key> must be ...``), the slots of :data:`GAIN_SLOTS` and
:data:`LOOP_GAIN_SLOTS` (``uh_controller_node.control_layout`` lays out its parameter vector by
them), the gains as ROS parameters (:func:`gain_parameters`) and the table of docs/scenario.md
(:func:`gains_markdown_table`).

The comparison cases of docs/control_law.md#comparison-cases are the same gains with exactly these changes:

* ``proposed``: as written;
* ``case1`` (non-optimal law): ``beta = 1`` (violates Lemma 2's ``beta >= 2``);
* ``case2`` (no serial-parallel estimation model): ``gamma = gamma_F = 0`` and ``kappa = 0`` in
  both loops, so the learning laws are driven by the tracking errors alone.
"""
from __future__ import annotations

import dataclasses
import math
from collections import UserDict
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Callable

from uh_topology.errors import ConfigError, ScenarioError
from uh_topology.schema import CONFIG_DIR, ConfigContext, format_key_path, parse_yaml, range_text, type_name

__all__ = ['CASES', 'GainsError', 'gains_source', 'scenario_gains', 'located',
           'Gain', 'GAINS', 'TOP_GAINS', 'LOOP_GAINS', 'LOOPS', 'GAIN_SLOTS', 'LOOP_GAIN_SLOTS',
           'RBFSpec', 'LoopGains', 'ControllerGains', 'GainParameter',
           'gain_parameters', 'nest_gains', 'gains_markdown_table']

#: The comparison cases of docs/control_law.md#comparison-cases, in report order.
CASES = ('proposed', 'case1', 'case2')
#: The two loops, as the gains file names them (mappings of loop gains).
LOOPS = ('outer', 'inner')
#: Where a gain is read: at the top of the file, in both loops, or in the inner loop only.
TOP, BOTH, INNER = 'top', 'loops', 'inner'


class GainsError(ScenarioError):
    """Controller gains that cannot be used: an entry unknown, missing or invalid, or an unknown case.

    A scenario's error, like the ``GainsFileError`` of a gains file that cannot be read
    (``uh_topology.errors``), so a caller that loads a scenario and builds its controllers catches
    either as a ``ScenarioError``. It reads ``<source>:<line>: <loop>: <what>``, the line when
    the gains were read with their lines (:func:`scenario_gains`).

    ``keys`` is the key path of the entry at fault inside the gains mapping (e.g. ``('outer', 'k')``),
    empty when the error is not about one entry.
    """

    def __init__(self, message: str, *, keys=(), path=None, source=None, line=None):
        self.keys = tuple(keys)
        super().__init__(message, path=path, source=source, line=line)


@dataclass(frozen=True)
class Gain:
    """One gain of the gains file, declared once: every other use of it is derived from this.

    Attributes
    ----------
    key, scope, meaning : str
        Its YAML key; where it is read: ``'top'``, ``'loops'`` (one value per loop) or ``'inner'``
        (the outer loop's record holds None, its parameter slot 0); what it is.
    unit, symbol : str or (str, str)
        Unit (``'-'``: none) and symbol of docs/control_law.md (empty: none); a pair
        ``(outer, inner)`` for a loop gain whose loops differ.
    minimum, strict, below, at_most : float or None, bool, float or None, float or None
        Allowed values: above ``minimum`` (``strict``) or at it, and under ``below`` or at most
        ``at_most``; None: no bound.
    integer : bool
        An integer (a count), not a float.
    field : str
        Attribute of the record (default ``key``); ``'rbf.low'``: attribute ``low`` of ``rbf``.
    default : float, str or None
        Value when the key is absent: a number, or the key (same mapping) whose value it takes;
        None: the key is required.
    slot, read_only : bool
        Has a slot in the kernels' parameter vector (in declaration order); sizes or places the
        networks, so it cannot change once the controller runs.
    convert : callable or None
        Maps the file's value to the record's (``math.radians`` for a value in degrees).
    note : str
        What else is allowed or required (docs table, parameter description).
    """

    key: str
    scope: str
    meaning: str
    unit: str | tuple = '-'
    symbol: str | tuple = ''
    minimum: float | None = 0
    strict: bool = True
    below: float | None = None
    at_most: float | None = None
    integer: bool = False
    field: str = ''
    default: float | str | None = None
    slot: bool = True
    read_only: bool = False
    convert: Callable | None = None
    note: str = ''

    @property
    def attr(self) -> str:
        """The record attribute that holds this gain (dotted for a member of a group)."""
        return self.field or self.key

    def applies_to(self, loop: str) -> bool:
        """Tell whether the loop ``loop`` (``'outer'``, ``'inner'``) has this gain."""
        return self.scope == BOTH or self.scope == loop

    def of_loop(self, value, loop: str | None):
        """Give the unit or symbol ``value`` of ``loop`` (a pair holds the outer's, then the inner's)."""
        return value[LOOPS.index(loop)] if isinstance(value, tuple) else value

    def allowed(self) -> str:
        """Say the values allowed as the docs table does (``'> 0'``, ``'integer >= 1'``, ``'(0, 90)'``)."""
        upper = self.below if self.at_most is None else self.at_most
        bounds = (range_text(self.minimum, upper, self.strict, self.at_most is None)
                  if self.minimum is not None or upper is not None else 'any number')
        text = ('integer ' if self.integer else '') + bounds
        if self.note:
            text += f'; {self.note}'
        if self.default is not None:
            default = f'`{self.default}`' if isinstance(self.default, str) else f'{self.default:g}'
            text += f'; optional, default {default}'
        return text

    def description(self, loop: str | None = None) -> str:
        """Describe it as a ROS parameter of ``loop`` (None: top level): ``'k1: first-error gain, 1/s'``."""
        symbol = self.of_loop(self.symbol, loop)
        text = (f'{symbol}: ' if symbol else '') + self.meaning + _unit_text(self.of_loop(self.unit, loop))
        return text + (f'; {self.note}' if self.note else '') + ('; fixed at start' if self.read_only else '')

    def symbol_unit(self, loop: str | None = None) -> str:
        """Give the symbol and unit of ``loop`` as the docs table does: ``'`k1`, 1/s'``, ``'m/s^2'``, ``'(-)'``."""
        symbol = self.of_loop(self.symbol, loop)
        return ((f'`{symbol}`' if symbol else '') + _unit_text(self.of_loop(self.unit, loop))).lstrip(', ')


def _unit_text(unit: str) -> str:
    """Give a unit as it follows a text: ``', 1/s'``, or ``' (-)'`` for none."""
    return ' (-)' if unit == '-' else f', {unit}'


_ACCEL = ('m/s^2', 'rad/s^2')     # outer / inner units of a fault estimate or a network output
_SPEED = ('m/s', 'rad/s')         # outer / inner units of a network input (RBF centres)

#: Every gain, in the order of the file, of the records and of the kernels' parameter vector.
GAINS = (
    Gain('beta', TOP, 'inverse-optimal factor', symbol='beta', note='Lemma 2 needs >= 2'),
    Gain('tilt_limit_deg', TOP, 'largest tilt of the thrust from vertical', unit='deg', below=90,
         field='tilt_limit', convert=math.radians),
    Gain('min_vertical_accel', TOP, 'smallest vertical specific thrust commanded', unit='m/s^2'),
    Gain('learning_phase', TOP, 'time after the first step in which the networks learn and the fault '
         'observers hold zero', unit='s', strict=False, default=0.0),
    Gain('feedforward_weight', TOP, "weight of the neighbours' velocities in the feed-forward f (the paper: 1); "
         'below 1 is a departure, a delay remedy (docs/delay.md#remedies)',
         symbol='w_f', at_most=1, default=1.0),
    Gain('k', BOTH, 'first-error gain', symbol=('k1', 'k3'), unit='1/s'),
    Gain('r', BOTH, 'inverse-optimal input weight', symbol=('r_p', 'r_w'), unit='s'),
    Gain('tau_command', BOTH, 'command filter time constant', symbol=('tau_1', 'tau_2'), unit='s'),
    Gain('tau_rate', INNER, 'filter time constant of alpha_w', symbol='tau_w', unit='s'),
    Gain('kappa', BOTH, 'SPEM correction gain', symbol=('kappa_p', 'kappa_w'), unit='1/s', strict=False),
    Gain('learning_rate', BOTH, 'network learning rate', symbol=('Gamma_p', 'Gamma_w'), unit='1/s',
         strict=False),
    Gain('gamma', BOTH, 'prediction-error weight in the weight law', symbol=('gamma_p', 'gamma_w'),
         strict=False),
    Gain('gamma_F', BOTH, 'prediction-error weight in the fault observer', symbol=('gamma_F,p', 'gamma_F,w'),
         strict=False),
    Gain('sigma', BOTH, 'weight leakage', symbol=('sigma_p', 'sigma_w'), strict=False),
    Gain('lambda', BOTH, 'fault observer gain', symbol=('lambda_p', 'lambda_w'), unit='1/s', strict=False,
         field='lambda_'),
    Gain('sigma_F', BOTH, 'fault-estimate leakage', symbol=('sigma_F,p', 'sigma_F,w'), strict=False),
    Gain('fault_bound', BOTH, 'projection bound of each fault-estimate component', unit=_ACCEL),
    Gain('weight_bound', BOTH, 'projection bound of each weight column norm', unit=_ACCEL),
    Gain('rbf_nodes', BOTH, 'RBF centres per axis', symbol='mu', minimum=1, strict=False, integer=True,
         field='rbf.nodes', slot=False, read_only=True),
    Gain('rbf_low', BOTH, 'first RBF centre', unit=_SPEED, minimum=None, field='rbf.low', read_only=True,
         note='< rbf_high unless one node'),
    Gain('rbf_high', BOTH, 'last RBF centre', unit=_SPEED, minimum=None, field='rbf.high', read_only=True),
    Gain('rbf_width', BOTH, 'Gaussian width of the RBFs', symbol='b', unit=_SPEED, field='rbf.width',
         read_only=True),
    Gain('late_learning_rate', BOTH, 'network learning rate after the learning phase',
         symbol=('Gamma_p', 'Gamma_w'), unit='1/s', strict=False, default='learning_rate'),
    Gain('late_sigma', BOTH, 'weight leakage after the learning phase', symbol=('sigma_p', 'sigma_w'),
         strict=False, default='sigma'),
)
#: The gains at the top of the file, and those of the loop mappings.
TOP_GAINS = tuple(g for g in GAINS if g.scope == TOP)
LOOP_GAINS = tuple(g for g in GAINS if g.scope != TOP)
#: Record attributes of the gains with a slot in the parameter vector: the top ones, one loop's.
GAIN_SLOTS = tuple(g.attr for g in TOP_GAINS if g.slot)
LOOP_GAIN_SLOTS = tuple(g.attr for g in LOOP_GAINS if g.slot)


# -- the records ------------------------------------------------------------------------------------
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


#: Records of the dotted fields of :data:`GAINS` (``'rbf.low'``): group -> class.
_GROUPS = {'rbf': RBFSpec}


def _by_field(gains):
    """Yield ``(attribute, gain)`` of the record fields holding ``gains``; a group once (gain None)."""
    seen = set()
    for g in gains:
        head = g.attr.partition('.')[0]
        if head not in seen:
            seen.add(head)
            yield head, None if head in _GROUPS else g


def _record_fields(gains) -> list:
    """Give ``(attribute, type)`` of the record fields holding ``gains``."""
    return [(head, _GROUPS[head] if g is None else int if g.integer else 'float | None' if g.scope == INNER
             else 'float') for head, g in _by_field(gains)]


def _attribute_docs(gains, per_loop: bool) -> str:
    """Write the numpydoc ``Attributes`` entries of the record fields holding ``gains``."""
    lines = []
    for head, g in _by_field(gains):
        if g is None:
            lines += [f'{head} : {_GROUPS[head].__name__}', f'    {_GROUPS[head].__doc__.splitlines()[0]}']
            continue
        what = ('; '.join(f'{loop}: {g.description(loop)}' for loop in LOOPS if g.applies_to(loop))
                if per_loop else g.description())
        key = f' (YAML key ``{g.key}``{", through " + g.convert.__name__ if g.convert else ""})' \
            if g.key != head else ''
        lines += [f'{head} : {"int" if g.integer else "float"}', f'    {what}{key}.']
    return '\n    '.join(lines)


def _record(name: str, doc: str, fields: list, base=object):
    """Make a frozen dataclass ``name`` of this module (picklable) with ``fields`` and ``doc``."""
    return dataclasses.make_dataclass(name, fields, bases=(base,), frozen=True,
                                      namespace={'__doc__': doc, '__module__': __name__})


LoopGains = _record('LoopGains', f"""Gains of one loop (outer: position/velocity; inner: attitude/rate).

    Attributes
    ----------
    {_attribute_docs(LOOP_GAINS, True)}
    """, _record_fields(LOOP_GAINS))


class _CaseMethods:
    """What :class:`ControllerGains` does besides holding the gains: read a mapping, derive a case."""

    __slots__ = ()

    @classmethod
    def from_mapping(cls, mapping, case: str = 'proposed', source: str = 'gains', lines=None):
        """Build the gains of ``case`` from a gains mapping (see module docstring).

        Parameters
        ----------
        mapping : dict
            Plain mapping or ``{'/**': {'ros__parameters': {...}}}``.
        case : str
            ``'proposed'``, ``'case1'`` or ``'case2'`` (docs/control_law.md#comparison-cases).
        source : str
            Where the mapping came from, used in error messages.
        lines : mapping, optional
            Key path -> line of the file (:func:`uh_topology.schema.parse_yaml`): errors then
            name the line of the entry at fault.

        Raises
        ------
        GainsError
            Unknown case; mapping not a dict; unknown or missing key; value not a finite number
            of the allowed range.
        """
        if case not in CASES:
            raise GainsError(f'unknown controller case {case!r}; allowed: {", ".join(CASES)}')
        gains = cls(case='proposed', **_GainsReader(source, {} if lines is None else lines).read(mapping))
        return gains.for_case(case)

    def for_case(self, case: str):
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


_TOP_REQUIRED = tuple(g for g in TOP_GAINS if g.default is None)
_TOP_OPTIONAL = tuple(g for g in TOP_GAINS if g.default is not None)   # a number as default: a record default
ControllerGains = _record('ControllerGains', f"""All gains of one UH controller for one comparison case.

    Attributes
    ----------
    case : str
        One of :data:`CASES`.
    outer, inner : LoopGains
        Gains of the position and attitude loops.
    {_attribute_docs(TOP_GAINS, False)}
    """, [('case', str), *_record_fields(_TOP_REQUIRED), *((loop, LoopGains) for loop in LOOPS),
          *((name, kind, dataclasses.field(default=g.default))
            for g, (name, kind) in zip(_TOP_OPTIONAL, _record_fields(_TOP_OPTIONAL), strict=False))],
    base=_CaseMethods)


# -- reading a gains mapping --------------------------------------------------------------------------
class _GainsReader:
    """Reads one gains mapping; its errors name the source, the line (when known) and the entry.

    ``lines`` is the key path -> line map of the file (may be empty), whose paths start with
    ``('/**', 'ros__parameters')`` when the gains are keyed so.
    """

    def __init__(self, source: str, lines):
        self.context = ConfigContext(source, lines)
        self.prefix = ()

    def error(self, keys, message: str, shown=()) -> GainsError:
        """Make the error about the entry ``keys``, its message after the key path ``shown``."""
        return GainsError(message, keys=keys, path=format_key_path(shown) or None, source=self.context.source,
                          line=self.context.line(self.prefix + tuple(keys)))

    def read(self, mapping) -> dict:
        """Read the fields of :class:`ControllerGains` (but ``case``) from a gains mapping."""
        data = self.unwrap(mapping)
        self.keys(data, (), [g.key for g in _TOP_REQUIRED] + list(LOOPS), [g.key for g in _TOP_OPTIONAL])
        fields = _fields(TOP_GAINS, self.values(data, (), TOP_GAINS))
        for loop in LOOPS:
            fields[loop] = self.loop(data, loop)
        return fields

    def unwrap(self, mapping) -> dict:
        """Give the gains of a plain or ``/**: ros__parameters:`` mapping."""
        if not isinstance(mapping, dict):
            raise self.error((), f'gains must be a mapping, got {type_name(mapping)}')
        if '/**' not in mapping:
            return mapping
        if set(mapping) != {'/**'}:
            raise self.error((), 'a "/**" keyed gains file may hold only the "/**" key')
        inner = mapping['/**']
        if not isinstance(inner, dict) or set(inner) != {'ros__parameters'} \
                or not isinstance(inner['ros__parameters'], dict):
            raise self.error((), '"/**" must hold exactly one mapping "ros__parameters"')
        self.prefix = ('/**', 'ros__parameters')
        return inner['ros__parameters']

    def keys(self, data: dict, at: tuple, required, optional):
        """Check that mapping ``data`` at key path ``at`` has every required key and no unknown one."""
        allowed = tuple(required) + tuple(optional)
        unknown = sorted(str(k) for k in data if k not in allowed)
        if unknown:
            raise self.error(at + (unknown[0],), f'unknown key(s) {unknown}; allowed: {", ".join(allowed)}', at)
        missing = [k for k in required if k not in data]
        if missing:
            raise self.error(at, f'missing key(s) {missing}', at)

    def loop(self, data: dict, loop: str):
        """Read the :class:`LoopGains` of the mapping of ``loop``."""
        mapping = data[loop]
        if not isinstance(mapping, dict):
            raise self.error((loop,), f'{loop} must be a mapping of loop gains, got {type_name(mapping)}')
        gains = [g for g in LOOP_GAINS if g.applies_to(loop)]
        self.keys(mapping, (loop,), [g.key for g in gains if g.default is None],
                  [g.key for g in gains if g.default is not None])
        values = self.values(mapping, (loop,), gains)
        if values['rbf_nodes'] > 1 and not values['rbf_low'] < values['rbf_high']:
            raise self.error((loop, 'rbf_low'), f'rbf_low must be < rbf_high, got {values["rbf_low"]!r} and '
                             f'{values["rbf_high"]!r}', (loop,))
        return LoopGains(**_fields(LOOP_GAINS, values))

    def values(self, data: dict, at: tuple, gains) -> dict:
        """Give ``{key: value}`` of ``gains`` in mapping ``data`` at ``at``, checked; defaults for absent ones."""
        out = {}
        for g in gains:
            if g.key in data:
                out[g.key] = self.value(g, data[g.key], at)
            else:
                out[g.key] = out[g.default] if isinstance(g.default, str) else g.default
        return out

    def value(self, gain: Gain, value, at: tuple):
        """Check one value of ``gain`` (at the mapping ``at``) and give it as the record holds it."""
        key, keys = gain.key, at + (gain.key,)
        if gain.integer:
            if isinstance(value, bool) or not isinstance(value, int) or not _within(gain, value) \
                    or (gain.below is not None and not value < gain.below):
                raise self.error(keys, f'{key} must be an integer {_bound_text(gain, gain.below)}, got {value!r}', at)
            return value
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(keys, f'{key} must be a number, got {value!r}', at)
        value = float(value)
        if not math.isfinite(value):
            raise self.error(keys, f'{key} must be finite, got {value!r}', at)
        if gain.minimum is not None and not _within(gain, value):
            raise self.error(keys, f'{key} must be {_bound_text(gain)}, got {value!r}', at)
        if gain.below is not None and not value < gain.below:
            raise self.error(keys, f'{key} must be < {gain.below:g}, got {value!r}', at)
        if gain.at_most is not None and not value <= gain.at_most:
            raise self.error(keys, f'{key} must be {_bound_text(gain)}, got {value!r}', at)
        return gain.convert(value) if gain.convert else value


def _within(gain: Gain, value) -> bool:
    """Tell whether ``value`` is at or above (strict: above) the gain's minimum."""
    return gain.minimum is None or value > gain.minimum or (not gain.strict and value == gain.minimum)


def _bound_text(gain: Gain, below=None) -> str:
    """Say the bounds as errors do: ``'> 0'``, ``'>= 1'`` (``below``: with that upper bound, ``'[1, 5)'``).

    A gain with ``at_most`` says its whole range: ``'(0, 1]'``.
    """
    if gain.at_most is not None:
        return range_text(gain.minimum, gain.at_most, gain.strict, False)
    return range_text(gain.minimum, below, gain.strict, True)


def _fields(gains, values: dict) -> dict:
    """Give the record fields of ``gains`` from ``{key: value}`` (absent: None), members gathered in their groups."""
    out = {}
    for g in gains:
        head, dot, member = g.attr.partition('.')
        if dot:
            out.setdefault(head, {})[member] = values.get(g.key)
        else:
            out[head] = values.get(g.key)
    return {name: _GROUPS[name](**value) if name in _GROUPS else value for name, value in out.items()}


# -- the gains of a scenario ---------------------------------------------------------------------------
class _FileLines(UserDict):
    """The key path -> line map of a YAML file, read when a line is first looked up (by an error)."""

    def __init__(self, path: Path, source: str):
        self.path, self.source = path, source

    @cached_property
    def data(self) -> dict:
        """Give the map (empty when the file cannot be read or parsed again)."""
        try:
            return parse_yaml(self.path.read_text(), self.source)[1]
        except (OSError, ConfigError):
            return {}


def gains_source(scenario) -> str:
    """How errors name a scenario's gains: the gains file, else ``gains of scenario '<name>'`` (inline gains)."""
    path = getattr(scenario, 'gains_path', None)
    return str(path) if path is not None else f'gains of scenario {getattr(scenario, "name", "?")!r}'


def _scenario_lines(scenario):
    """Give the line map of the scenario's gains file (read on first use), or None for inline gains."""
    path = getattr(scenario, 'gains_path', None)
    return _FileLines(path, gains_source(scenario)) if path is not None else None


def scenario_gains(scenario, case: str) -> 'ControllerGains':
    """Build the gains of ``case`` from a scenario's gains; an error names the gains file and the line."""
    return ControllerGains.from_mapping(scenario.gains, case, source=gains_source(scenario),
                                        lines=_scenario_lines(scenario))


def located(exc: GainsError, scenario) -> GainsError:
    """Give ``exc`` (an error of the scenario's gains read without lines) with the line of its entry.

    ``exc`` itself when it has a line already, or the gains are inline.
    """
    lines = _scenario_lines(scenario)
    if exc.line is not None or lines is None or exc.source != gains_source(scenario):
        return exc
    prefix = ('/**', 'ros__parameters') if '/**' in scenario.gains else ()
    return GainsError(exc.message, keys=exc.keys, path=exc.path, source=exc.source,
                      line=ConfigContext(exc.source, lines).line(prefix + exc.keys))


# -- the gains as ROS parameters (docs/control_law.md#gains-as-parameters) -------------------------
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


_BY_KEY = {(TOP, g.key): g for g in TOP_GAINS} | {(loop, g.key): g for g in LOOP_GAINS for loop in LOOPS
                                                    if g.applies_to(loop)}


def gain_parameters(mapping, source: str = 'gains') -> list:
    """List the gains of ``mapping`` as :class:`GainParameter`, in file order.

    ``mapping`` is plain or ``/**: ros__parameters:``, validated as by
    :meth:`ControllerGains.from_mapping`; the loops' gains have dotted names (``outer.k``).
    """
    ControllerGains.from_mapping(mapping, 'proposed', source)   # validate first: clear errors
    data = _GainsReader(source, {}).unwrap(mapping)
    out = []
    for key, value in data.items():
        if isinstance(value, dict):
            out += [_gain_parameter(f'{key}.{sub}', _BY_KEY[key, sub], sub_value, key)
                    for sub, sub_value in value.items()]
        else:
            out.append(_gain_parameter(key, _BY_KEY[TOP, key], value, None))
    return out


def _gain_parameter(name: str, gain: Gain, value, loop) -> GainParameter:
    minimum = None if gain.minimum is None else float(gain.minimum)
    return GainParameter(name, int(value) if gain.integer else float(value), gain.description(loop), minimum,
                         gain.read_only)


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


# -- the table of docs/scenario.md#gains-file ---------------------------------------------------------
def gains_markdown_table(example=None) -> str:
    """Write the tables of the gains file in docs/scenario.md: the top-level keys, then the loop keys.

    ``example`` is a gains mapping whose values fill the last column(s) (default: the paper
    scenario's, ``uh_topology/config/paper_gains.yaml``); an absent optional key is left empty.
    """
    if example is None:
        example = parse_yaml((CONFIG_DIR / 'paper_gains.yaml').read_text(), 'paper_gains.yaml')[0]
    data = _GainsReader('example', {}).unwrap(example)
    rows = ['| key | meaning | symbol, unit | allowed | paper |', '|---|---|---|---|---:|']
    rows += [f'| `{g.key}` | {g.meaning} | {g.symbol_unit()} | {g.allowed()} | {_cell(data.get(g.key))} |'
             for g in TOP_GAINS]
    rows += ['', '| loop key | meaning | outer: symbol, unit | inner: symbol, unit | allowed | paper outer | '
             'paper inner |', '|---|---|---|---|---|---:|---:|']
    for g in LOOP_GAINS:
        units = [g.symbol_unit(loop) if g.applies_to(loop) else '(not allowed)' for loop in LOOPS]
        values = [_cell(data.get(loop, {}).get(g.key)) for loop in LOOPS]
        rows.append(f'| `{g.key}` | {g.meaning} | {" | ".join(units)} | {g.allowed()} | {" | ".join(values)} |')
    return '\n'.join(rows) + '\n'


def _cell(value) -> str:
    """Write a value of the example column: ``2``, ``0.025``, ``11``; empty when absent."""
    if value is None:
        return ''
    return str(value) if isinstance(value, int) else f'{value:g}'
