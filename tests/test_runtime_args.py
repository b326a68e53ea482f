"""ROS names, ``--ros-args`` and parameter files as rcl handles them (uh_runtime.dds.arguments).

Also the parameter value checks of uh_runtime.dds.parameters. Pure: no DDS.
"""
import pytest

from uh_runtime.dds.arguments import (
    InvalidNameError,
    RemapRule,
    RosArgsError,
    expand_topic_name,
    load_params_file,
    node_pattern_matches,
    parse_ros_args,
    remap_topic,
    remove_ros_args,
)
from uh_runtime.dds.parameters import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    ParameterType,
    check_value,
)


@pytest.mark.parametrize('name, ns, expected', [
    ('state', '/uh1', '/uh1/state'),
    ('state', '/', '/state'),
    ('~/debug', '/uh1', '/uh1/sim/debug'),
    ('~', '/uh1', '/uh1/sim'),
    ('~/debug', '/', '/sim/debug'),
    ('/clock', '/uh1', '/clock'),
    ('{node}/x', '/a/b', '/a/b/sim/x'),
    ('nested/name', '/uh1', '/uh1/nested/name'),
])
def test_topic_names_expand_like_rcl(name, ns, expected):
    assert expand_topic_name(name, 'sim', ns) == expected


@pytest.mark.parametrize('name', ['', '2fast', 'a//b', 'trailing/', 'bad-char', '~x'])
def test_invalid_topic_names_are_rejected(name):
    with pytest.raises(InvalidNameError):
        expand_topic_name(name, 'sim', '/uh1')


def test_ros_args_sections_and_typed_values():
    parsed = parse_ros_args([
        'prog', 'mine', '--ros-args', '-p', 'i:=3', '-p', 'f:=1.5', '-p', 'b:=true',
        '-p', 's:=hello', '-p', 'l:=[1, 2]', '-p', 'e:=1e-3', '-p', "q:='5'", '-p', 'sim:x:=2',
        '-r', '__ns:=/uh1', '-r', 'sim:state:=/other', '--log-level', 'debug',
        '--log-level', 'uh1.sim:=warn', '--enable-rosout-logs', '--', 'tail', '--ros-args',
        '--remap', 'a:=b'])
    values = {}
    for pattern, params in parsed.parameters:
        for name, value in params.items():
            values[name] = (pattern, value)
    assert values == {'i': ('/**', 3), 'f': ('/**', 1.5), 'b': ('/**', True),
                      's': ('/**', 'hello'), 'l': ('/**', [1, 2]), 'e': ('/**', 0.001),
                      'q': ('/**', '5'), 'x': ('sim', 2)}
    assert type(values['f'][1]) is float and type(values['i'][1]) is int
    assert parsed.remaps == [RemapRule(None, '__ns', '/uh1'), RemapRule('sim', 'state', '/other'),
                             RemapRule(None, 'a', 'b')]
    assert parsed.log_levels == {'': 'DEBUG', 'uh1.sim': 'WARN'}
    assert parsed.unparsed == ['prog', 'mine', 'tail']
    assert remove_ros_args(['prog', '--ros-args', '-p', 'a:=1', '--', 'x']) == ['prog', 'x']


@pytest.mark.parametrize('args, message', [
    (['--ros-args', '--unknown'], "Found unknown ROS argument '--unknown'"),
    (['--ros-args', '-p'], 'ROS argument -p needs a value'),
    (['--ros-args', '-p', 'novalue'], "parameter rule 'novalue' must have the form name:=value"),
    (['--ros-args', '-r', 'x'], "remap rule 'x' must have the form [node:]from:=to"),
    (['--ros-args', '--log-level', 'loud'], "log level 'loud' is not one of"),
    (['--ros-args', '--params-file', '/nonexistent/p.yaml'], 'cannot read parameter file'),
])
def test_malformed_ros_args_are_clear_errors(args, message):
    with pytest.raises(RosArgsError, match=message.replace('[', r'\[').replace(']', r'\]')):
        parse_ros_args(args)


def test_remaps_apply_to_the_expanded_name_and_only_to_the_named_node():
    rules = [RemapRule('ctl', 'state', '/x'), RemapRule(None, '~/dbg', 'debug'),
             RemapRule(None, '/uh1/state', 'state2')]
    assert remap_topic(rules, '/uh1/state', 'ctl', '/uh1') == '/x'
    assert remap_topic(rules, '/uh1/state', 'sim', '/uh1') == '/uh1/state2'
    assert remap_topic(rules, '/uh1/sim/dbg', 'sim', '/uh1') == '/uh1/debug'
    assert remap_topic(rules, '/uh1/other', 'sim', '/uh1') == '/uh1/other'


def test_params_file_keys_nesting_and_wildcards(tmp_path):
    path = tmp_path / 'p.yaml'
    path.write_text(
        '/**:\n  ros__parameters:\n    rate: 10.0  # Hz\n    gains: {k1: 2, k2: 1e-3}\n'
        '/uh1/sim:\n  ros__parameters:\n    uh_id: 1\n'
        'uh2:\n  sim:\n    ros__parameters:\n      uh_id: 2\n'
        '/**/controller:\n  ros__parameters:\n    case: case1\n')
    entries = load_params_file(path)
    assert entries == [('/**', {'rate': 10.0, 'gains.k1': 2, 'gains.k2': 0.001}),
                       ('/uh1/sim', {'uh_id': 1}), ('/uh2/sim', {'uh_id': 2}),
                       ('/**/controller', {'case': 'case1'})]
    bad = tmp_path / 'bad.yaml'
    bad.write_text('/**:\n  ros__parameters: 3\n')
    with pytest.raises(RosArgsError, match='"ros__parameters" of /\\*\\* must be a mapping'):
        load_params_file(bad)
    bad.write_text('/**:\n  rate: 3\n')
    with pytest.raises(RosArgsError, match="key 'rate' under /\\*\\* is neither a node name"):
        load_params_file(bad)


@pytest.mark.parametrize('pattern, node, matches', [
    ('/**', '/uh1/sim', True), ('/**', '/sim', True), ('/uh1/sim', '/uh1/sim', True),
    ('/uh1/sim', '/uh2/sim', False), ('/**/sim', '/uh1/sim', True), ('/**/sim', '/sim', True),
    ('/**/sim', '/uh1/controller', False), ('/*/sim', '/uh1/sim', True),
    ('/*/sim', '/a/b/sim', False), ('sim', '/sim', True), ('/uh*/sim', '/uh12/sim', True),
])
def test_node_keys_match_like_rcl(pattern, node, matches):
    assert node_pattern_matches(pattern, node) is matches


def test_range_checks_name_what_is_allowed():
    ints = ParameterDescriptor(integer_range=[IntegerRange(from_value=1, to_value=9, step=2)])
    assert check_value('n', 1, ints) is None and check_value('n', 9, ints) is None
    assert check_value('n', 4, ints) == 'allowed range is [1, 9] in steps of 2 from 1'
    assert check_value('n', 11, ints) == 'allowed range is [1, 9] in steps of 2 from 1'
    floats = ParameterDescriptor(floating_point_range=[FloatingPointRange(from_value=0.0, to_value=1.0)])
    assert check_value('x', 1.0, floats) is None and check_value('x', 0.0, floats) is None
    assert check_value('x', 1.5, floats) == 'allowed range is [0.0, 1.0]'
    assert 'NaN is not allowed' in check_value('x', float('nan'), floats)


def test_parameter_types_follow_rclpy():
    assert ParameterType.from_parameter_value(True) == ParameterType.BOOL
    assert ParameterType.from_parameter_value(3) == ParameterType.INTEGER
    assert ParameterType.from_parameter_value(3.0) == ParameterType.DOUBLE
    assert ParameterType.from_parameter_value(['a']) == ParameterType.STRING_ARRAY
    assert ParameterType.from_parameter_value([1.0, 2.0]) == ParameterType.DOUBLE_ARRAY
    assert not ParameterType.DOUBLE.check(3)  # rclpy: no int for a double parameter
    with pytest.raises(TypeError, match='not a parameter value'):
        ParameterType.from_parameter_value([1, 'a'])
