"""Backend selection and the facade's names (``import uh_runtime as rt``).

The rclpy path cannot run here (rclpy is not installable); a stand-in ``rclpy`` made of plain
module objects, injected into ``sys.modules`` of a child process, checks that the facade re-exports
rclpy's own objects and that the message module imports the rosidl classes.
"""
import os
import subprocess
import sys
import textwrap

import pytest

from uh_runtime.backend import BackendError, select_backend

CONTRACT_NAMES = [
    'init', 'spin', 'spin_once', 'try_shutdown', 'ok', 'Node', 'ExternalShutdownException',
    'ParameterDescriptor', 'IntegerRange', 'FloatingPointRange', 'QoSProfile', 'ReliabilityPolicy',
    'DurabilityPolicy', 'HistoryPolicy', 'Parameter', 'SetParametersResult',
    'MultiThreadedExecutor', 'SingleThreadedExecutor', 'run_node', 'check_parameter_overrides',
]


def _importer(available):
    def importer(name):
        if available:
            return object()
        raise ImportError(f'No module named {name!r}')
    return importer


@pytest.mark.parametrize('env, available, expected', [
    ({}, True, 'rclpy'),
    ({}, False, 'dds'),
    ({'UH_BACKEND': 'dds'}, True, 'dds'),
    ({'UH_BACKEND': 'DDS'}, False, 'dds'),
    ({'UH_BACKEND': 'rclpy'}, True, 'rclpy'),
])
def test_backend_selection(env, available, expected):
    assert select_backend(env, _importer(available)) == expected


def test_rclpy_demanded_but_missing_is_a_clear_error():
    with pytest.raises(BackendError, match='UH_BACKEND=rclpy but rclpy cannot be imported'):
        select_backend({'UH_BACKEND': 'rclpy'}, _importer(False))
    with pytest.raises(BackendError, match="UH_BACKEND='zenoh' is not a known backend"):
        select_backend({'UH_BACKEND': 'zenoh'}, _importer(True))


def _run(code, tmp_path, **env):
    import os
    full_env = dict(os.environ, **env)
    return subprocess.run([sys.executable, '-c', textwrap.dedent(code)], capture_output=True,
                          text=True, timeout=60, cwd=tmp_path, env=full_env)


def test_facade_exposes_the_contract_names_on_the_dds_backend(tmp_path):
    result = _run(f"""
        import uh_runtime as rt
        from uh_runtime import messages
        missing = [n for n in {CONTRACT_NAMES!r} if not hasattr(rt, n)]
        print(rt.BACKEND, messages.BACKEND, missing, rt.Node.__module__)
    """, tmp_path, UH_BACKEND='dds')
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ['dds', 'dds', '[]', 'uh_runtime.dds.node']


def test_sub_packages_export_their_names_and_load_only_the_modules_asked_for(tmp_path):
    # uh_runtime.lazy_exports: a module of a sub-package loads alone, and python -m runs one without a warning
    result = _run("""
        import sys
        from uh_runtime import bags, dds
        from uh_runtime.cli import uh as cli
        from uh_runtime.backend import FACADE_NAMES
        from uh_runtime.bags.bag_reader import BagError
        loaded = sorted(m for m in sys.modules if m.startswith(('uh_runtime.bags', 'uh_runtime.cli.uh')))
        print(sorted(dds.__all__) == sorted(FACADE_NAMES), loaded, bags.BagError is BagError)
        print(all(getattr(package, name) is not None for package in (bags, cli, dds) for name in package.__all__))
    """, tmp_path, UH_BACKEND='dds')
    assert result.returncode == 0, result.stderr
    assert result.stdout.split('\n')[:2] == [
        "True ['uh_runtime.bags', 'uh_runtime.bags.bag_reader', 'uh_runtime.cli.uh'] True", 'True']
    for module in ('uh_runtime.bags.bag', 'uh_runtime.bags.replay', 'uh_runtime.cli.uh'):
        run = subprocess.run([sys.executable, '-P', '-W', 'error', '-m', module, '--help'], capture_output=True,
                             text=True, timeout=60, env=dict(os.environ, UH_BACKEND='dds'))
        assert run.returncode == 0 and not run.stderr, (module, run.stderr)


def test_facade_reexports_rclpy_objects_when_rclpy_is_importable(tmp_path):
    result = _run(f"""
        import sys, types

        def module(name, **attrs):
            mod = types.ModuleType(name)
            mod.__dict__.update(attrs)
            sys.modules[name] = mod
            if '.' in name:
                parent, _, child = name.rpartition('.')
                setattr(sys.modules[parent], child, mod)
            return mod

        def cls(name):
            return type(name, (), {{}})

        class Parameter:
            Type = cls('Type')

        class ExternalShutdownException(Exception):
            pass

        rclpy = module('rclpy', init=lambda *, args=None, context=None: None, ok=lambda: True,
                       shutdown=lambda: None, try_shutdown=lambda: None, spin=lambda n: None,
                       spin_once=lambda n, **k: None, spin_until_future_complete=lambda *a: None,
                       get_global_executor=lambda: None)
        exc = module('rclpy.exceptions', NotInitializedException=cls('NIE'))
        for n in ['InvalidParameterTypeException', 'InvalidParameterValueException',
                  'ParameterAlreadyDeclaredException', 'ParameterException',
                  'ParameterNotDeclaredException', 'ParameterUninitializedException',
                  'InvalidHandle']:
            setattr(exc, n, cls(n))
        module('rclpy.clock', Clock=cls('Clock'), ClockType=cls('ClockType'), ROSClock=cls('ROSClock'))
        module('rclpy.context', Context=cls('Context'))
        module('rclpy.duration', Duration=cls('Duration'))
        module('rclpy.executors', Executor=cls('E'), ExternalShutdownException=ExternalShutdownException,
               MultiThreadedExecutor=cls('M'), SingleThreadedExecutor=cls('S'))
        module('rclpy.logging', get_logger=lambda name: name)
        module('rclpy.node', Node=cls('Node'))
        module('rclpy.parameter', Parameter=Parameter)
        module('rclpy.publisher', Publisher=cls('Publisher'))
        module('rclpy.qos', **{{n: cls(n) for n in ['DurabilityPolicy', 'HistoryPolicy',
               'LivelinessPolicy', 'QoSProfile', 'ReliabilityPolicy', 'qos_profile_sensor_data',
               'qos_profile_system_default']}})
        module('rclpy.subscription', Subscription=cls('Subscription'))
        module('rclpy.time', Time=cls('Time'))
        module('rclpy.timer', Timer=cls('Timer'))
        module('rclpy.utilities', get_default_context=lambda: None, remove_ros_args=lambda a: a,
               timeout_sec_to_nsec=lambda t: -1)
        module('rclpy.impl')
        module('rclpy.impl.implementation_singleton', rclpy_implementation=None)
        module('rclpy.waitable', NumberOfEntities=cls('NumberOfEntities'))
        module('rcl_interfaces')
        module('rcl_interfaces.msg', **{{n: cls(n) for n in ['FloatingPointRange', 'IntegerRange',
               'ParameterDescriptor', 'SetParametersResult']}})
        module('uh_msgs')
        module('uh_msgs.msg', UHState=cls('UHState'))

        import rclpy.node, rclpy.executors, rcl_interfaces.msg, uh_msgs.msg
        import uh_runtime as rt
        from uh_runtime import messages
        checks = [rt.BACKEND == 'rclpy', rt.Node is rclpy.node.Node, rt.init is rclpy.init,
                  rt.ExternalShutdownException is rclpy.executors.ExternalShutdownException,
                  rt.ParameterDescriptor is rcl_interfaces.msg.ParameterDescriptor,
                  rt.ParameterType is rclpy.parameter.Parameter.Type,
                  messages.UHState is uh_msgs.msg.UHState,
                  messages.get_message('uh_msgs/msg/UHState') is uh_msgs.msg.UHState,
                  rt.init(args=['x']) is None,
                  issubclass(rt.StaticSingleThreadedExecutor, rclpy.executors.SingleThreadedExecutor)]
        missing = [n for n in {CONTRACT_NAMES!r} if not hasattr(rt, n)]
        print(checks, missing)
    """, tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == f"{[True] * 10} []"


def test_uh_backend_rclpy_without_rclpy_fails_at_import(tmp_path):
    result = _run('import uh_runtime', tmp_path, UH_BACKEND='rclpy')
    assert result.returncode != 0
    assert 'UH_BACKEND=rclpy but rclpy cannot be imported' in result.stderr


@pytest.mark.parametrize('freeze, frozen, young', [('', True, 10_000), ('0', False, 700)])
def test_a_spinning_node_has_its_start_up_frozen_and_a_larger_young_generation(freeze, frozen, young):
    # what run_node does to the garbage collector before it spins (uh_runtime/runner.py): measured
    # to cut a 40-UH single process's step time by a fifth; UH_GC_FREEZE=0 keeps Python's defaults
    code = textwrap.dedent('''
        import gc
        from uh_runtime import runner
        runner._freeze_startup_objects()
        print(gc.get_freeze_count() > 0, gc.get_threshold()[0], runner.GC_YOUNG_THRESHOLD)
    ''')
    env = {k: v for k, v in os.environ.items() if k != 'UH_GC_FREEZE'}
    if freeze:
        env['UH_GC_FREEZE'] = freeze
    result = subprocess.run([sys.executable, '-P', '-c', code], env=env, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == [str(frozen), str(young), '10000']
