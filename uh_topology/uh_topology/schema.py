"""The schema of every YAML configuration file: scenario, gains, campaign spec, impairments.

What the readers of those files share, so that each reports its errors the same way,
``<file>:<line>: <key path>: <what was wrong>; <what is allowed>`` (docs/scenario.md):

* :func:`parse_yaml` -- the YAML parse that rejects repeated keys and keeps the line of every key
  path;
* :class:`ConfigContext` -- formats errors with file, line and key path, and reads typed values
  (mapping, number, integer, string, vector, UH id, channel) with one wording of every error;
* :func:`type_name`, :func:`unit_suffix`, :func:`range_text`, :func:`format_key_path` -- the
  pieces of those messages;
* :func:`read_config_file` -- a YAML file by path, or a bundled one (``uh_topology/config``) by name;
* :func:`read_text_file` -- a file's UTF-8 text, refused in one error when it is not UTF-8;
* :class:`ConfigError` -- the base of every configuration error (:mod:`uh_topology.errors`).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import yaml

from uh_core.layout import CHANNEL_ALIASES

from . import errors as E
from .errors import ConfigError

__all__ = [
    'CONFIG_DIR', 'ConfigError', 'ConfigContext', 'parse_yaml', 'line_map', 'format_key_path', 'type_name',
    'unit_suffix', 'range_text', 'read_only_array', 'read_config_file', 'read_text_file',
]

#: The directory of the bundled configuration files (scenarios, gains, campaign specs).
CONFIG_DIR = Path(__file__).resolve().parent / 'config'


# ------------------------------------------------------------------------------------------------
# YAML with duplicate-key detection and line numbers


class _Loader(yaml.SafeLoader):
    """Safe loader that rejects repeated keys in a mapping."""

    def construct_mapping(self, node, deep=False):
        """Build a mapping, refusing keys that are not scalars or appear twice."""
        self.flatten_mapping(node)
        seen = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            try:
                hash(key)
            except TypeError:
                raise E.WrongTypeError(f'mapping keys must be scalars, got {type(key).__name__}',
                                       source=getattr(self, '_source', None),
                                       line=key_node.start_mark.line + 1) from None
            if key in seen:
                raise E.DuplicateKeyError(
                    f'key {key!r} repeated (first at line {seen[key]}); each key may appear once',
                    source=getattr(self, '_source', None), line=key_node.start_mark.line + 1)
            seen[key] = key_node.start_mark.line + 1
        return super().construct_mapping(node, deep=deep)


def line_map(node, path=(), out=None) -> dict:
    """Map every key path (a tuple) of a YAML node tree to the 1-based line of its key or item."""
    if out is None:
        out = {(): node.start_mark.line + 1}
    if isinstance(node, yaml.MappingNode):
        for k, v in node.value:
            p = path + (str(k.value),)
            out.setdefault(p, k.start_mark.line + 1)
            line_map(v, p, out)
    elif isinstance(node, yaml.SequenceNode):
        for i, v in enumerate(node.value):
            p = path + (i,)
            out.setdefault(p, v.start_mark.line + 1)
            line_map(v, p, out)
    return out


def parse_yaml(text: str, source: str | None) -> tuple:
    """Parse YAML text into ``(data, lines)``: the data, and the key path -> line map of :func:`line_map`.

    An empty document gives ``(None, {})``. Raises :class:`~uh_topology.errors.ScenarioSyntaxError`
    (with the line of the problem) for invalid YAML, :class:`~uh_topology.errors.DuplicateKeyError`
    for a repeated key; ``source`` names the file in the messages.
    """
    loader = _Loader(text)
    loader._source = source
    try:
        node = loader.get_single_node()
        if node is None:
            return None, {}
        data = loader.construct_document(node)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        problem = exc.problem or exc.context or 'invalid YAML'
        raise E.ScenarioSyntaxError(f'YAML syntax error: {problem}', source=source,
                                    line=mark.line + 1 if mark else None) from None
    except yaml.YAMLError as exc:
        raise E.ScenarioSyntaxError(f'YAML syntax error: {exc}', source=source) from None
    finally:
        loader.dispose()
    return data, line_map(node)


# ------------------------------------------------------------------------------------------------
# Pieces of the messages


def format_key_path(path) -> str:
    """Write a key path tuple as text: ``('edges', 3, 'weight')`` -> ``'edges[3].weight'``."""
    out = ''
    for p in path:
        out += f'[{p}]' if isinstance(p, int) else (f'.{p}' if out else str(p))
    return out


def type_name(value) -> str:
    """Name the YAML type of a value for a message (``'null'`` for None)."""
    return 'null' if value is None else type(value).__name__


def unit_suffix(unit: str) -> str:
    """Give ``' (m)'`` for unit ``'m'``, nothing for no unit."""
    return f' ({unit})' if unit else ''


def range_text(lo, hi, lo_open: bool, hi_open: bool) -> str:
    """Describe an allowed range: ``'[0.0, 1.0)'``, ``'>= 0'`` or ``'< 5'``."""
    if lo is not None and hi is not None:
        return f'{"(" if lo_open else "["}{lo}, {hi}{")" if hi_open else "]"}'
    if lo is not None:
        return f'{">" if lo_open else ">="} {lo}'
    return f'{"<" if hi_open else "<="} {hi}'


def read_only_array(values) -> np.ndarray:
    """Copy values into a float array that cannot be written."""
    arr = np.array(values, dtype=float)
    arr.setflags(write=False)
    return arr


# ------------------------------------------------------------------------------------------------
# Errors with file, line and key path; typed readers


class ConfigContext:
    """Reports errors with file, line and key path, and reads typed values of one YAML file.

    Parameters
    ----------
    source : str or None
        The file (``None`` for in-memory data).
    lines : dict
        Key path -> line map of :func:`parse_yaml` (empty: no lines in the messages).
    """

    def __init__(self, source: str | None, lines: dict):
        self.source = source
        self.lines = lines

    def line(self, path):
        """Give the line of a key path, or of its nearest ancestor the map knows (None if none)."""
        path = tuple(p if isinstance(p, int) else str(p) for p in path)
        while path:
            if path in self.lines:
                return self.lines[path]
            path = path[:-1]
        return self.lines.get(())

    def error(self, cls, path, message, **kwargs):
        """Build an error of class ``cls`` at a key path (the caller raises it)."""
        return cls(message, path=format_key_path(path) or None, source=self.source, line=self.line(path),
                   **kwargs)

    def mapping(self, value, path, required=(), optional=(), what='a mapping'):
        """Check that a value is a mapping with all ``required`` keys and no key beyond ``optional``."""
        if not isinstance(value, dict):
            raise self.error(E.WrongTypeError, path, f'expected {what}, got {type_name(value)}')
        allowed = list(required) + list(optional)
        for key in value:
            if key not in allowed:
                raise self.error(E.UnknownKeyError, path + (key,),
                                 f'unknown key {key!r}; allowed keys here: {", ".join(allowed)}')
        for key in required:
            if key not in value:
                raise self.error(E.MissingFieldError, path,
                                 f'missing required key {key!r} (required: {", ".join(required)})')
        return value

    def number(self, value, path, *, lo=None, hi=None, lo_open=False, hi_open=False, unit=''):
        """Read a finite number (as float) within the given bounds, in ``unit``."""
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(E.WrongTypeError, path,
                             f'expected a number{unit_suffix(unit)}, got {type_name(value)} {value!r}')
        value = float(value)
        if not math.isfinite(value):
            raise self.error(E.NonFiniteError, path, f'expected a finite number{unit_suffix(unit)}, got {value!r}')
        bad = ((lo is not None and (value <= lo if lo_open else value < lo))
               or (hi is not None and (value >= hi if hi_open else value > hi)))
        if bad:
            raise self.error(E.InvalidValueError, path, f'value {value!r} out of range; allowed: '
                             f'{range_text(lo, hi, lo_open, hi_open)}{unit_suffix(unit)}')
        return value

    def integer(self, value, path, *, lo=None, what='an integer'):
        """Read an integer (not a bool) >= ``lo``; ``what`` names it in the type error."""
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(E.WrongTypeError, path, f'expected {what}, got {type_name(value)} {value!r}')
        if lo is not None and value < lo:
            raise self.error(E.InvalidValueError, path, f'value {value} out of range; allowed: >= {lo}')
        return value

    def string(self, value, path, choices=None):
        """Read a string, one of ``choices`` when given."""
        if not isinstance(value, str):
            raise self.error(E.WrongTypeError, path, f'expected a string, got {type_name(value)} {value!r}')
        if choices is not None and value not in choices:
            raise self.error(E.InvalidValueError, path,
                             f'{value!r} is not allowed; allowed: {", ".join(choices)}')
        return value

    def boolean(self, value, path):
        """Read ``true`` or ``false``."""
        if not isinstance(value, bool):
            raise self.error(E.WrongTypeError, path, f'expected true or false, got {type_name(value)} {value!r}')
        return value

    def vector(self, value, path, size=3, unit=''):
        """Read a list of ``size`` finite numbers in ``unit`` as a read-only float array."""
        if not isinstance(value, list) or len(value) != size:
            raise self.error(E.WrongTypeError, path, f'expected a list of {size} numbers{unit_suffix(unit)}, '
                             f'got {type_name(value)} {value!r}')
        return read_only_array([self.number(v, path + (i,), unit=unit) for i, v in enumerate(value)])

    def uh_id(self, value, path, known, what='UH id'):
        """Read a UH id, one of ``known``."""
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(E.WrongTypeError, path,
                             f'expected an integer {what}, got {type_name(value)} {value!r}')
        if value not in known:
            hint = ('; id 0 is the virtual leader: link leaders to it under reference_links'
                    if value == 0 else '')
            raise self.error(E.UnknownIdError, path,
                             f'{what} {value} is not a UH of this scenario; known ids: '
                             f'{sorted(known)}{hint}')
        return value

    def channel(self, value, path) -> int:
        """Read an input channel: an index 0..3 or a name of ``uh_core.layout.CHANNEL_ALIASES``."""
        if isinstance(value, str):
            if value not in CHANNEL_ALIASES:
                raise self.error(E.InvalidValueError, path,
                                 f'unknown channel {value!r}; allowed: 0..3 or {", ".join(CHANNEL_ALIASES)}')
            return CHANNEL_ALIASES[value]
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(E.WrongTypeError, path,
                             f'expected a channel index 0..3 or name, got {type_name(value)}')
        if not 0 <= value <= 3:
            raise self.error(E.InvalidValueError, path,
                             f'channel {value} out of range; allowed: 0..3 or {", ".join(CHANNEL_ALIASES)}')
        return value


# ------------------------------------------------------------------------------------------------
# Files


def read_config_file(path_or_name, what: str, bundled_names, base_dir=None) -> tuple[Path, str]:
    """Read a YAML file, or a bundled one, as ``(path, text)``.

    A relative name is taken relative to ``base_dir`` (default the current directory); when
    ``path_or_name`` is a bare name and no such file exists, the bundled file
    ``uh_topology/config/<name>.yaml`` is read. ``what`` names the kind of file and
    ``bundled_names()`` the bundled ones in the error message
    (:class:`~uh_topology.errors.ScenarioNotFoundError`).
    """
    text = str(path_or_name)
    if not text.strip():
        raise E.ScenarioNotFoundError(f'{what} {text!r}: give a path to a YAML file or a bundled name '
                                      f'({", ".join(bundled_names()) or "none"})')
    path = Path(text)
    if base_dir is not None and not path.is_absolute():
        path = Path(base_dir) / path
    if path.is_dir():
        raise E.ScenarioNotFoundError(f'{what} {text!r} is a directory; give a YAML file or a bundled name '
                                      f'({", ".join(bundled_names()) or "none"})')
    if not path.is_file():
        bundled = CONFIG_DIR / f'{text}.yaml'
        if Path(text).suffix == '' and Path(text).parent == Path('.') and bundled.is_file():
            path = bundled
        else:
            where = f' (relative to {str(base_dir)!r})' if base_dir is not None else ''
            raise E.ScenarioNotFoundError(
                f'no {what} file {text!r}{where}; give a path to a YAML file or a bundled name '
                f'({", ".join(bundled_names()) or "none"})')
    try:
        return path, read_text_file(path)
    except OSError as exc:
        raise E.ScenarioNotFoundError(f'cannot read {str(path)!r}: {exc.strerror}') from None


def read_text_file(path) -> str:
    """Read the text of a configuration file, which must be UTF-8 (ASCII is).

    Line ends are read as in Python's text mode (CR LF and CR as LF). Raises ``OSError`` when the file
    cannot be read, and :class:`~uh_topology.errors.ScenarioSyntaxError` when it is not UTF-8 text,
    naming the file, the line and the first byte that is not:
    ``team.yaml:12: not UTF-8 text: byte 0x80 at offset 345; allowed: a YAML text file in UTF-8``.
    """
    data = Path(path).read_bytes()
    try:
        text = data.decode('utf-8')
    except UnicodeDecodeError as exc:
        line = data.count(b'\n', 0, exc.start) + 1
        raise E.ScenarioSyntaxError(f'not UTF-8 text: byte 0x{data[exc.start]:02x} at offset {exc.start}; '
                                    'allowed: a YAML text file in UTF-8', source=str(path), line=line) from None
    return text.replace('\r\n', '\n').replace('\r', '\n')
