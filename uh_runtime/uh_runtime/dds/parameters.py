"""Parameters of the Cyclone DDS backend, with rclpy's (Jazzy) classes, semantics and checks.

``Parameter``, ``Parameter.Type``, ``ParameterDescriptor``, ``IntegerRange``,
``FloatingPointRange``, ``SetParametersResult`` mirror ``rclpy.parameter`` and
``rcl_interfaces.msg``. Values are typed as ROS types them (bool, int, float, str, byte array and
arrays of those). Errors name the parameter and say what is allowed.
"""
import enum
import math
from dataclasses import dataclass, field

__all__ = [
    'Parameter', 'ParameterType', 'ParameterDescriptor', 'IntegerRange', 'FloatingPointRange',
    'SetParametersResult', 'ParameterException', 'ParameterNotDeclaredException',
    'ParameterAlreadyDeclaredException', 'InvalidParameterTypeException',
    'InvalidParameterValueException', 'ParameterImmutableException',
    'ParameterUninitializedException', 'UnknownParameterOverrideError', 'check_value',
]


class ParameterException(Exception):
    """Base class of the parameter errors (rclpy.exceptions.ParameterException)."""


class ParameterNotDeclaredException(ParameterException):
    """A parameter that was never declared is read or set: ``name``, and the ``declared`` names listed."""

    def __init__(self, name, declared=()):
        declared = sorted(declared)
        super().__init__(
            f"parameter '{name}' is not declared"
            + (f"; declared parameters: {', '.join(declared)}" if declared else ''))
        self.name = name


class ParameterAlreadyDeclaredException(ParameterException):
    """Parameter ``name`` is declared twice."""

    def __init__(self, name):
        super().__init__(f"parameter '{name}' has already been declared")


class InvalidParameterTypeException(ParameterException):
    """Parameter ``name`` of type ``expected`` (a :class:`ParameterType`) is given ``value`` of another type."""

    def __init__(self, name, value, expected):
        got = ParameterType.from_parameter_value(value).name
        super().__init__(
            f"parameter '{name}': value {value!r} has type {got}, "
            f"allowed type is {expected.name}")
        self.name = name


class InvalidParameterValueException(ParameterException):
    """The ``value`` of parameter ``name`` that the descriptor (range, read-only) or an on-set callback rejects.

    ``reason`` says why.
    """

    def __init__(self, name, value, reason):
        super().__init__(f"parameter '{name}': value {value!r} rejected: {reason}")
        self.name = name
        self.reason = reason


class ParameterImmutableException(ParameterException):
    """Read-only parameter ``name`` is set after its declaration."""

    def __init__(self, name):
        super().__init__(f"parameter '{name}' is read-only and cannot be set after declaration")


class ParameterUninitializedException(ParameterException):
    """Parameter ``name``, declared with a type but no value, is read before it was set."""

    def __init__(self, name):
        super().__init__(f"parameter '{name}' is declared without a value and has not been set")


class UnknownParameterOverrideError(ParameterException):
    """A parameter override (``-p``, ``--params-file``) names a parameter the node never declares.

    ``node_name``; the ``unknown`` overridden names and the ``declared`` ones, both kept sorted.
    """

    def __init__(self, node_name, unknown, declared):
        unknown = sorted(unknown)
        declared = sorted(declared)
        super().__init__(
            f"node '{node_name}' does not declare parameter"
            f"{'s' if len(unknown) > 1 else ''} {', '.join(repr(u) for u in unknown)}; "
            f"declared parameters: {', '.join(declared) if declared else '(none)'}")
        self.unknown = unknown
        self.declared = declared


class ParameterType(enum.IntEnum):
    """rclpy ``Parameter.Type`` (values are rcl_interfaces ParameterType constants)."""

    NOT_SET = 0
    BOOL = 1
    INTEGER = 2
    DOUBLE = 3
    STRING = 4
    BYTE_ARRAY = 5
    BOOL_ARRAY = 6
    INTEGER_ARRAY = 7
    DOUBLE_ARRAY = 8
    STRING_ARRAY = 9

    @classmethod
    def from_parameter_value(cls, value):
        """Type of a Python value, as rclpy infers it; :class:`TypeError` for unsupported values."""
        if value is None:
            return cls.NOT_SET
        if isinstance(value, bool):
            return cls.BOOL
        if isinstance(value, int):
            return cls.INTEGER
        if isinstance(value, float):
            return cls.DOUBLE
        if isinstance(value, str):
            return cls.STRING
        if isinstance(value, (bytes, bytearray)):
            return cls.BYTE_ARRAY
        if type(value).__module__ == 'numpy':
            return cls.from_parameter_value(value.tolist())
        if isinstance(value, (list, tuple)):
            if all(isinstance(v, bytes) for v in value) and value:
                return cls.BYTE_ARRAY
            if all(isinstance(v, bool) for v in value):
                return cls.BOOL_ARRAY
            if all(isinstance(v, int) and not isinstance(v, bool) for v in value):
                return cls.INTEGER_ARRAY
            if all(isinstance(v, float) for v in value):
                return cls.DOUBLE_ARRAY
            if all(isinstance(v, str) for v in value):
                return cls.STRING_ARRAY
        raise TypeError(
            f'{value!r} is not a parameter value; allowed: bool, int, float, str, bytes '
            'or a list of one of those (not mixed)')

    def check(self, value) -> bool:
        """Return True if ``value`` has this type."""
        try:
            return ParameterType.from_parameter_value(value) == self or (
                self != ParameterType.NOT_SET and isinstance(value, (list, tuple)) and not value
                and self.name.endswith('_ARRAY'))
        except TypeError:
            return False


class Parameter:
    """rclpy ``Parameter(name, type_=None, value=None)``."""

    Type = ParameterType

    def __init__(self, name, type_=None, value=None):
        if type_ is None:
            type_ = ParameterType.from_parameter_value(value)
        if not isinstance(type_, ParameterType):
            raise TypeError(f"parameter '{name}': type_ must be a Parameter.Type, got {type_!r}")
        if value is not None and not type_.check(value):
            raise ValueError(f"parameter '{name}': type {type_.name} does not match value {value!r}")
        self._name = name
        self._type = type_
        self._value = list(value) if isinstance(value, tuple) else value

    @property
    def name(self):
        """The parameter's name, as rclpy's ``Parameter.name``."""
        return self._name

    @property
    def type_(self):
        """The parameter's :class:`ParameterType` (``NOT_SET`` without a value), as rclpy's ``Parameter.type_``."""
        return self._type

    @property
    def value(self):
        """The parameter's value (a list for array types; None when not set), as rclpy's ``Parameter.value``."""
        return self._value

    def get_parameter_value(self):
        """Return the value itself (rclpy returns a ``ParameterValue`` message; this backend the Python value)."""
        return self._value

    def __repr__(self):
        return f'Parameter({self._name!r}, {self._type.name}, {self._value!r})'

    def __eq__(self, other):
        return (isinstance(other, Parameter) and self.name == other.name
                and self.type_ == other.type_ and self.value == other.value)


@dataclass
class IntegerRange:
    """rcl_interfaces/msg/IntegerRange: inclusive ``from_value .. to_value``, ``step`` 0 = any."""

    from_value: int = 0
    to_value: int = 0
    step: int = 0


@dataclass
class FloatingPointRange:
    """rcl_interfaces/msg/FloatingPointRange: inclusive ``from_value .. to_value``, ``step`` 0 = any."""

    from_value: float = 0.0
    to_value: float = 0.0
    step: float = 0.0


@dataclass
class ParameterDescriptor:
    """rcl_interfaces/msg/ParameterDescriptor (ranges are lists of at most one element, as in ROS)."""

    name: str = ''
    type: int = 0
    description: str = ''
    additional_constraints: str = ''
    read_only: bool = False
    dynamic_typing: bool = False
    floating_point_range: list = field(default_factory=list)
    integer_range: list = field(default_factory=list)


@dataclass
class SetParametersResult:
    """rcl_interfaces/msg/SetParametersResult."""

    successful: bool = False
    reason: str = ''


def _range_text(rng) -> str:
    text = f'[{rng.from_value}, {rng.to_value}]'
    if rng.step:
        text += f' in steps of {rng.step} from {rng.from_value}'
    return text


def check_value(name, value, descriptor: ParameterDescriptor):
    """Return ``None`` if ``value`` satisfies the ranges of ``descriptor``, else the reason.

    Follows rclpy: a value equal to a bound is accepted; with a step, the value must be a whole
    number of steps from ``from_value`` (or equal ``to_value``); floating-point comparisons use a
    relative tolerance of 1e-9 (rclpy uses ``math.isclose`` with its defaults).
    """
    if descriptor.integer_range and isinstance(value, int) and not isinstance(value, bool):
        rng = descriptor.integer_range[0]
        ok = rng.from_value <= value <= rng.to_value and (
            not rng.step or value == rng.to_value or (value - rng.from_value) % rng.step == 0)
        if not ok:
            return f'allowed range is {_range_text(rng)}'
    if descriptor.floating_point_range and isinstance(value, float):
        rng = descriptor.floating_point_range[0]
        if math.isnan(value):
            return f'NaN is not allowed; allowed range is {_range_text(rng)}'
        inside = (rng.from_value <= value <= rng.to_value or math.isclose(value, rng.from_value)
                  or math.isclose(value, rng.to_value))
        if inside and rng.step and not math.isclose(value, rng.to_value):
            steps = (value - rng.from_value) / rng.step
            inside = math.isclose(steps, round(steps), abs_tol=1e-9)
        if not inside:
            return f'allowed range is {_range_text(rng)}'
    return None
