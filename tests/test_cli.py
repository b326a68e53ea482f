"""The ``uh`` inspection CLI: help, errors, and the commands against a running node.

The main listing/echo checks against a node in another process are in test_runtime_dds.py; here
the CLI runs in-process (``uh_runtime.cli.uh.main``) next to a node of this process's own context.
"""
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from spinning import spinning_in_thread

from uh_runtime import dds as rt
from uh_runtime import messages
from uh_runtime.cli import uh as cli
from uh_runtime.dds.qos import DurabilityPolicy, QoSProfile

BOUND = 10.0  # s; bounds a failure only


@pytest.mark.parametrize('argv', [
    [], ['topic'], ['topic', 'list'], ['topic', 'echo'], ['topic', 'hz'], ['topic', 'info'],
    ['node'], ['node', 'list'],
])
def test_help_everywhere(argv, capsys):
    with pytest.raises(SystemExit) as exit_info:
        cli.main([*argv, '--help'])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith('usage: uh')
    if argv[-1:] in (['list'], ['echo'], ['hz'], ['info']):
        assert '--domain-id' in out


def test_console_script_is_installed_and_exits_non_zero_on_errors(tmp_path):
    script = Path(sys.executable).with_name('uh')
    assert script.is_file()
    result = subprocess.run([str(script), 'topic', 'list', '--domain-id', '300'],
                            capture_output=True, text=True, cwd=tmp_path, timeout=60)
    assert result.returncode == 2      # bad input
    assert 'uh: error: --domain-id 300 is outside 0..232' in result.stderr


def test_unknown_topic_and_bad_type_are_clear_errors(domain_id, capsys):
    assert cli.main(['topic', 'info', '/missing', '--spin-time', '0.2']) == 1
    assert "uh: error: Unknown topic '/missing'" in capsys.readouterr().err
    # a type or a field given on the command line that does not exist is bad input (2)
    assert cli.main(['topic', 'echo', '/x', 'nope/msg/Bad', '--timeout', '0.2']) == 2
    assert "unknown message type 'nope/msg/Bad'" in capsys.readouterr().err
    assert cli.main(['topic', 'echo', '/x', 'uh_msgs/msg/UHState', '--field', 'position.w']) == 2
    assert "'position.w' is not a field of UHState (no 'w' in Vector3)" in capsys.readouterr().err


@pytest.fixture
def running(domain_id):
    """Run a node in a thread of this process publishing a latched Reference and a stream of states."""
    ctx = rt.Context()
    ctx.init(args=['test'])
    node = rt.Node('leader', namespace='/team', context=ctx)
    latched = node.create_publisher(
        messages.Reference, 'reference',
        QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    ref = messages.Reference()
    ref.step = 12
    ref.position.z = 30.0
    latched.publish(ref)
    pub = node.create_publisher(messages.UHState, 'state', 10)

    def tick():
        msg = messages.UHState()
        msg.uh_id = 7
        pub.publish(msg)
    node.create_timer(0.02, tick)
    executor = rt.SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    with spinning_in_thread(executor, ctx, BOUND):
        yield node
    ctx.try_shutdown()


def test_echo_of_a_latched_topic_and_node_count(running, capsys):
    assert cli.main(['topic', 'echo', '/team/reference', '--once', '--timeout', str(BOUND)]) == 0
    text, sep, rest = capsys.readouterr().out.partition('---\n')
    msg = yaml.safe_load(text)
    assert sep and msg['step'] == 12 and msg['position']['z'] == 30.0
    assert cli.main(['topic', 'hz', '/team/state', '--timeout', '3']) == 0
    out = capsys.readouterr().out
    assert 'average rate: ' in out and 'window: ' in out
    assert cli.main(['topic', 'info', '/team/reference', '-v']) == 0
    out = capsys.readouterr().out
    assert 'Durability: TRANSIENT_LOCAL' in out and 'Node namespace: /team' in out
