"""Exception types of configuration loading and topology validation (docs/graph.md, docs/scenario.md).

Every error is a :class:`ConfigError` (a ``ValueError``); those of a scenario, of the files it
names (gains) and of a campaign spec are :class:`ScenarioError`. Each carries where it happened:

* ``source`` -- the file (or ``None`` for in-memory data),
* ``line`` -- the 1-based line in that file when known,
* ``path`` -- the key path inside the file, e.g. ``edges[3].weight``.

The message reads ``<source>:<line>: <path>: <what was wrong>; <what is allowed>``.
:mod:`uh_topology.schema` reads the YAML and builds these errors.
"""
from __future__ import annotations

__all__ = [
    'ConfigError', 'ScenarioError', 'ScenarioNotFoundError', 'ScenarioSyntaxError', 'SchemaError',
    'UnknownKeyError', 'MissingFieldError', 'WrongTypeError', 'NonFiniteError',
    'InvalidValueError', 'DuplicateKeyError', 'TopologyError', 'DuplicateIdError',
    'IdNumberingError', 'UnknownIdError', 'SelfLoopError', 'NegativeWeightError',
    'DuplicateEdgeError', 'LeaderHearsFollowerError', 'FollowerLinkedToReferenceError',
    'MissingOffsetError', 'FollowerOffsetError', 'UnreachableLeaderError',
    'UnreachableFollowerError', 'LaplacianConditionError', 'DuplicateFaultError',
    'GainsFileError',
]


class ConfigError(ValueError):
    """Base class: a configuration file (or in-memory configuration) that cannot be used.

    Parameters
    ----------
    message : str
        What was wrong and what is allowed.
    path : str, optional
        Key path inside the file (``edges[3].weight``).
    source : str, optional
        File the configuration came from.
    line : int, optional
        1-based line in ``source``.
    """

    def __init__(self, message: str, *, path: str | None = None, source: str | None = None,
                 line: int | None = None):
        self.message = message
        self.path = path
        self.source = source
        self.line = line
        where = ''
        if source is not None:
            where = f'{source}:{line}: ' if line is not None else f'{source}: '
        elif line is not None:
            where = f'line {line}: '
        if path:
            where += f'{path}: '
        super().__init__(where + message)


class ScenarioError(ConfigError):
    """A scenario, a file it names, or a campaign spec that cannot be used."""


class ScenarioNotFoundError(ScenarioError):
    """The scenario file (or a file it names) does not exist."""


class ScenarioSyntaxError(ScenarioError):
    """The file is not valid YAML (the line of the problem is in ``line``)."""


class SchemaError(ScenarioError):
    """Base of the structural errors: keys, types, values."""


class UnknownKeyError(SchemaError):
    """A key the scenario format does not know (typo?)."""


class MissingFieldError(SchemaError):
    """A required key is missing."""


class WrongTypeError(SchemaError):
    """A value has the wrong type (e.g. a string where a number is required)."""


class NonFiniteError(SchemaError):
    """A number is NaN or infinite."""


class InvalidValueError(SchemaError):
    """A value of the right type outside its allowed range or set."""


class DuplicateKeyError(SchemaError):
    """A mapping repeats a key (YAML would silently keep the last one)."""


class GainsFileError(ScenarioError):
    """The gains file a scenario names cannot be read or does not hold a mapping (``Scenario.gains``).

    What the gains say is checked by the gains loader, ``uh_controller_node.gains``, which raises its
    own ``GainsError``.
    """


class TopologyError(ScenarioError):
    """Base of the errors of the communication graph and the team roles."""


class DuplicateIdError(TopologyError):
    """Two UHs share an id."""


class IdNumberingError(TopologyError):
    """Ids are not 1..N+M with the leaders first (0 is reserved for the virtual leader)."""


class UnknownIdError(TopologyError):
    """An edge, link or fault names an id that is not a UH of the scenario."""


class SelfLoopError(TopologyError):
    """An edge from a UH to itself."""


class NegativeWeightError(TopologyError):
    """An edge or virtual-leader link with a negative weight."""


class DuplicateEdgeError(TopologyError):
    """The same directed edge (or virtual-leader link) is listed twice."""


class LeaderHearsFollowerError(TopologyError):
    """A leader listens to a follower (leaders only hear leaders and the virtual leader)."""


class FollowerLinkedToReferenceError(TopologyError):
    """A follower hears the virtual leader (only leaders may)."""


class MissingOffsetError(TopologyError):
    """A leader has no formation offset h_i."""


class FollowerOffsetError(TopologyError):
    """A follower was given a formation offset (followers' targets come from the leaders)."""


class UnreachableLeaderError(TopologyError):
    """Assumption 1 fails: no directed path from the virtual leader to the leaders ``ids``.

    Other arguments as :class:`ConfigError`'s (message, path, source, line).
    """

    def __init__(self, message: str, *, ids=(), **kwargs):
        self.ids = tuple(ids)
        super().__init__(message, **kwargs)


class UnreachableFollowerError(TopologyError):
    """Assumption 1 fails: no directed path from any leader to the followers ``ids``.

    Other arguments as :class:`ConfigError`'s (message, path, source, line).
    """

    def __init__(self, message: str, *, ids=(), **kwargs):
        self.ids = tuple(ids)
        super().__init__(message, **kwargs)


class LaplacianConditionError(TopologyError):
    """Lemma 1 fails.

    L1 has an eigenvalue with non-positive real part, or -L1^-1 L2 is not a matrix of convex
    weights with the reachability pattern of the graph.
    """


class DuplicateFaultError(SchemaError):
    """Two faults on the same channel of the same UH."""
