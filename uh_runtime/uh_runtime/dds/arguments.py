"""ROS 2 names and command-line arguments, as rcl does them (Jazzy), for the Cyclone DDS backend.

* :func:`expand_topic_name` and :func:`validate_*` follow ``rcl_expand_topic_name`` and
  ``rmw_validate_*``: ``state`` in namespace ``/uh1`` -> ``/uh1/state``; ``~/x`` -> ``/uh1/sim/x``;
  ``{node}``/``{ns}`` substitutions; absolute names unchanged.
* :func:`parse_ros_args` reads the ``--ros-args ... [--]`` sections: ``-p name:=value`` (value
  typed as YAML, like rcl), ``-r [node:]from:=to`` (``__ns``, ``__node``/``__name`` and topic
  remaps), ``--params-file FILE`` (``/**:``, ``/ns/node:``, ``node:`` keys with
  ``ros__parameters``), ``--log-level [logger:=]LEVEL``, ``-e/--enclave``; unknown ROS flags are an
  error like in rcl.
"""
import fnmatch
import re
from dataclasses import dataclass, field
from pathlib import Path

import yaml

__all__ = [
    'RosArgsError', 'InvalidNameError', 'ParsedArguments', 'RemapRule', 'parse_ros_args',
    'remove_ros_args', 'expand_topic_name', 'validate_node_name', 'validate_namespace',
    'validate_full_topic_name', 'parse_parameter_value', 'load_params_file', 'LOG_LEVELS',
]

LOG_LEVELS = {'DEBUG': 10, 'INFO': 20, 'WARN': 30, 'WARNING': 30, 'ERROR': 40, 'FATAL': 50}
_TOKEN = re.compile(r'^[A-Za-z_][A-Za-z0-9_]*$')
_FLAGS_NO_ARG = {
    '--enable-rosout-logs', '--disable-rosout-logs', '--enable-stdout-logs',
    '--disable-stdout-logs', '--enable-external-lib-logs', '--disable-external-lib-logs',
}
_FLAGS_IGNORED_WITH_ARG = {'--log-config-file', '--log-file-name'}


class RosArgsError(ValueError):
    """Malformed ``--ros-args`` (unknown flag, missing value, bad rule, unreadable params file)."""


class InvalidNameError(ValueError):
    """A node name, namespace or topic name that ROS 2 would reject."""


def validate_node_name(name: str) -> str:
    """Return ``name`` if it is a valid ROS node name, else raise :class:`InvalidNameError`."""
    if not name or not _TOKEN.match(name):
        raise InvalidNameError(
            f'invalid node name {name!r}: must be non-empty, start with a letter or underscore and '
            'contain only letters, digits and underscores')
    return name


def validate_namespace(namespace: str) -> str:
    """Return ``namespace`` if it is a valid absolute ROS namespace, else raise."""
    if namespace == '/':
        return namespace
    if not namespace.startswith('/') or namespace.endswith('/') or any(
            not _TOKEN.match(tok) for tok in namespace[1:].split('/')):
        raise InvalidNameError(
            f'invalid namespace {namespace!r}: must be absolute ("/" or "/a/b"), tokens of '
            'letters, digits and underscores not starting with a digit, no trailing "/"')
    return namespace


def validate_full_topic_name(name: str) -> str:
    """Return ``name`` if it is a valid fully qualified topic name, else raise."""
    if not name.startswith('/') or name == '/' or name.endswith('/') or any(
            not _TOKEN.match(tok) for tok in name[1:].split('/')):
        raise InvalidNameError(
            f'invalid topic name {name!r}: after expansion it must be absolute, tokens of letters, '
            'digits and underscores not starting with a digit, separated by single "/"')
    return name


def normalise_namespace(namespace) -> str:
    """Apply rclpy's handling of the ``namespace`` argument: ``None``/'' -> '/', relative -> absolute."""
    if not namespace:
        return '/'
    if not namespace.startswith('/'):
        namespace = '/' + namespace
    return validate_namespace(namespace)


def expand_topic_name(name: str, node_name: str, namespace: str) -> str:
    """Fully qualified topic name of ``name`` for a node ``node_name`` in ``namespace``."""
    if not name:
        raise InvalidNameError('topic name must not be empty')
    ns = namespace.rstrip('/')
    name = name.replace('{node}', node_name).replace('{ns}', ns or '/').replace('{namespace}', ns or '/')
    if name.startswith('~'):
        rest = name[1:]
        if rest and not rest.startswith('/'):
            raise InvalidNameError(f'invalid topic name {name!r}: "~" must be followed by "/" or nothing')
        name = f'{ns}/{node_name}{rest}'
    elif not name.startswith('/'):
        name = f'{ns}/{name}'
    return validate_full_topic_name(name)


@dataclass
class RemapRule:
    """One ``-r [node:]from:=to`` rule."""

    node: str | None
    match: str
    replacement: str


@dataclass
class ParsedArguments:
    """Result of :func:`parse_ros_args`."""

    remaps: list = field(default_factory=list)
    #: list of (node-name pattern, {name: value}) in command-line order
    parameters: list = field(default_factory=list)
    log_levels: dict = field(default_factory=dict)  # logger name ('' = default) -> level name
    enclave: str | None = None
    unparsed: list = field(default_factory=list)  # non-ROS arguments
    rosout_logs: bool = True   # --disable-rosout-logs turns the /rosout publisher off

    def extend(self, other: 'ParsedArguments'):
        """Append ``other``'s remaps and parameters to these; its log levels and its enclave (if set) override these.

        ``rosout_logs`` stays True only if both have it.
        """
        self.remaps += other.remaps
        self.parameters += other.parameters
        self.log_levels.update(other.log_levels)
        self.enclave = other.enclave or self.enclave
        self.rosout_logs = self.rosout_logs and other.rosout_logs


class _RosYamlLoader(yaml.SafeLoader):
    """YAML 1.1 as PyYAML reads it, plus ``1e-3`` (no dot) as a float, as rcl's parser does."""


_RosYamlLoader.add_implicit_resolver(
    'tag:yaml.org,2002:float',
    re.compile(r'^[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)$'),
    list('-+0123456789'))


def parse_parameter_value(text: str):
    """Type a ``-p name:=value`` value as rcl does: YAML scalars and flow sequences.

    ``true`` -> bool, ``3`` -> int, ``3.0`` / ``1e-3`` -> float, ``[1, 2]`` -> list of int,
    anything else -> str.
    """
    try:
        value = yaml.load(text, Loader=_RosYamlLoader)
    except yaml.YAMLError:
        return text
    return _yaml_to_param(text, value)


def _yaml_to_param(text, value):
    if value is None:
        return text
    if isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, list):
        return [_yaml_to_param(str(v), v) for v in value]
    return text


def _split_rule(rule: str, form: str):
    """Split ``[node:]name:=value`` into ``(node or None, name, value)``; ``form`` names the rule in errors."""
    if ':=' not in rule:
        raise RosArgsError(f'{form[0]} {rule!r} must have the form {form[1]}')
    left, right = rule.split(':=', 1)
    node = None
    if ':' in left:
        node, left = left.split(':', 1)
    return node, left, right


def _parse_rule(rule: str) -> RemapRule:
    node, left, replacement = _split_rule(rule, ('remap rule', '[node:]from:=to'))
    if not left or not replacement:
        raise RosArgsError(f'remap rule {rule!r} must have the form [node:]from:=to')
    return RemapRule(node, left, replacement)


def _flatten_params(prefix, mapping, out, where):
    for key, value in mapping.items():
        name = f'{prefix}.{key}' if prefix else str(key)
        if isinstance(value, dict):
            _flatten_params(name, value, out, where)
        else:
            out[name] = _yaml_to_param(str(value), value)


def load_params_file(path) -> list:
    """Read a ROS 2 parameter YAML file: list of (node pattern, {name: value}).

    Keys are node names (``/**``, ``/ns/node``, ``node``, wildcards ``*`` and ``**``), possibly
    nested (``uh1: {sim: {ros__parameters: ...}}``), each holding ``ros__parameters``; nested
    parameter mappings are flattened with ``.`` like rcl.
    """
    path = Path(path)
    try:
        data = yaml.load(path.read_text(), Loader=_RosYamlLoader)
    except OSError as exc:
        raise RosArgsError(f'cannot read parameter file {path}: {exc.strerror}') from exc
    except yaml.YAMLError as exc:
        raise RosArgsError(f'parameter file {path} is not valid YAML: {exc}') from exc
    if not isinstance(data, dict):
        raise RosArgsError(f'parameter file {path} must map node names to "ros__parameters"')
    result = []

    def walk(prefix, mapping):
        for key, value in mapping.items():
            if key == 'ros__parameters':
                if not isinstance(value, dict):
                    raise RosArgsError(f'{path}: "ros__parameters" of {prefix or "/"} must be a mapping')
                params = {}
                _flatten_params('', value, params, path)
                result.append((prefix or '/**', params))
            elif isinstance(value, dict):
                walk(f"{prefix.rstrip('/')}/{str(key).strip('/')}", value)
            else:
                raise RosArgsError(
                    f'{path}: key {key!r} under {prefix or "the top level"} is neither a node name '
                    'nor "ros__parameters"')

    walk('', data)
    return result


def node_pattern_matches(pattern: str, fq_node_name: str) -> bool:
    """Return True if a parameter-file node key matches the fully qualified node name (rcl rules)."""
    if not pattern.startswith('/'):
        pattern = '/' + pattern
    if pattern in ('/**', '/*'):
        return pattern == '/**' or fq_node_name.count('/') == 1
    regex = ''
    for token in pattern.split('/')[1:]:
        if token == '**':
            regex += '(/[^/]+)*'
        else:
            regex += '/' + fnmatch.translate(token).replace('\\Z', '').replace('(?s:', '(?:').replace('.*', '[^/]*')
    return re.fullmatch(regex, fq_node_name) is not None


def parse_ros_args(args) -> ParsedArguments:
    """Parse every ``--ros-args`` section of ``args`` (the program name included or not)."""
    parsed = ParsedArguments()
    args = list(args or [])
    i = 0
    in_ros = False
    while i < len(args):
        arg = args[i]
        if arg == '--ros-args':
            in_ros = True
            i += 1
            continue
        if not in_ros:
            parsed.unparsed.append(arg)
            i += 1
            continue
        if arg == '--':
            in_ros = False
            i += 1
            continue

        def value(flag, i=i):   # called in this iteration, before ``i`` moves on
            if i + 1 >= len(args) or args[i + 1] in ('--ros-args', '--'):
                raise RosArgsError(f'ROS argument {flag} needs a value')
            return args[i + 1]

        if arg in ('-p', '--param'):
            rule = value(arg)
            node, name, text = _split_rule(rule, ('parameter rule', 'name:=value'))
            if not name:
                raise RosArgsError(f'parameter rule {rule!r} has an empty name')
            parsed.parameters.append(
                ('/**' if node is None else node, {name: parse_parameter_value(text)}))
            i += 2
        elif arg in ('-r', '--remap'):
            parsed.remaps.append(_parse_rule(value(arg)))
            i += 2
        elif arg == '--params-file':
            parsed.parameters.extend(load_params_file(value(arg)))
            i += 2
        elif arg == '--log-level':
            text = value(arg)
            logger, _, level = text.rpartition(':=')
            if level.upper() not in LOG_LEVELS:
                raise RosArgsError(
                    f'log level {level!r} is not one of {", ".join(sorted(set(LOG_LEVELS) - {"WARNING"}))}')
            parsed.log_levels[logger] = level.upper()
            i += 2
        elif arg in ('-e', '--enclave'):
            parsed.enclave = value(arg)
            i += 2
        elif arg in _FLAGS_NO_ARG:
            if arg in ('--disable-rosout-logs', '--enable-rosout-logs'):
                parsed.rosout_logs = arg == '--enable-rosout-logs'
            i += 1
        elif arg in _FLAGS_IGNORED_WITH_ARG:
            value(arg)
            i += 2
        else:
            raise RosArgsError(
                f'Found unknown ROS argument {arg!r}; known: -p/--param, -r/--remap, --params-file, '
                '--log-level, -e/--enclave')
    return parsed


def remove_ros_args(args) -> list:
    """``args`` without the ``--ros-args`` sections (like ``rclpy.utilities.remove_ros_args``)."""
    return parse_ros_args(args).unparsed if args is not None else []


def apply_name_remaps(rules, node_name: str):
    """(node name, namespace or None) after ``__node``/``__name`` and ``__ns`` rules for this node."""
    new_name, new_ns = node_name, None
    for rule in rules:
        if rule.node is not None and rule.node != node_name:
            continue
        if rule.match in ('__node', '__name'):
            new_name = validate_node_name(rule.replacement)
        elif rule.match == '__ns':
            new_ns = normalise_namespace(rule.replacement)
    return new_name, new_ns


def remap_topic(rules, fq_name: str, node_name: str, namespace: str) -> str:
    """Apply the first matching topic remap rule to a fully qualified topic name (rcl semantics)."""
    for rule in rules:
        if rule.match.startswith('__'):
            continue
        if rule.node is not None and rule.node != node_name:
            continue
        try:
            match = expand_topic_name(rule.match, node_name, namespace)
        except InvalidNameError:
            continue
        if match == fq_name:
            return expand_topic_name(rule.replacement, node_name, namespace)
    return fq_name
