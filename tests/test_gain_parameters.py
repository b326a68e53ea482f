"""Controller gains as ROS parameters (docs/control_law.md#gains-as-parameters).

They are declared from the scenario's gains file with descriptions and ranges, overridden by
``--params-file``, changed live through the parameter services, validated like the file (rejected
with the reason, the old value kept), logged, and used by the control law from the next step.
"""
import math
from pathlib import Path

import pytest
import yaml
from spinning import spinning_in_thread

from uh_controller_node.gains import ControllerGains, gain_parameters, nest_gains
from uh_topology.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
GAINS_FILE = ROOT / 'uh_topology' / 'uh_topology' / 'config' / 'paper_gains.yaml'
BOUND = 10.0   # s; bounds a failure only


def test_gain_parameters_flatten_the_file_and_nest_back_to_the_same_gains():
    mapping = yaml.safe_load(GAINS_FILE.read_text())
    params = gain_parameters(mapping)
    names = [p.name for p in params]
    assert names[:4] == ['beta', 'tilt_limit_deg', 'min_vertical_accel', 'learning_phase']
    assert 'outer.k' in names and 'inner.late_sigma' in names and 'inner.tau_rate' in names
    assert len(names) == len(set(names)) == 4 + 16 + 19
    by_name = {p.name: p for p in params}
    assert by_name['outer.rbf_nodes'].value == 11 and by_name['outer.rbf_nodes'].read_only
    assert not by_name['outer.k'].read_only and by_name['outer.k'].minimum == 0.0
    assert by_name['inner.rbf_low'].minimum is None        # a centre may be negative
    assert all(p.description for p in params)
    flat = {p.name: p.value for p in params}
    assert ControllerGains.from_mapping(nest_gains(flat)) == ControllerGains.from_mapping(mapping)


@pytest.fixture
def controller(domain_id, tmp_path):
    """Spin the UH3 controller node of the paper scenario (realtime) in a thread.

    Its gains are overridden by a /**: parameters file; the fixture also gives a caller context.
    """
    from uh_controller_node.controller_node import ControllerNode
    from uh_runtime import dds as rt
    override = tmp_path / 'gains.yaml'
    override.write_text('/**:\n  ros__parameters:\n    outer:\n      k: 1.3\n')
    ctx = rt.Context()
    ctx.init(args=['controller'])
    node = ControllerNode(context=ctx, cli_args=['--ros-args', '-r', '__ns:=/uh3', '-p', 'uh_id:=3',
                                                 '-p', 'clock_mode:=realtime', '--params-file', str(override)])
    executor = rt.SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    caller = rt.Context()
    caller.init(args=['caller'])
    with spinning_in_thread(executor, ctx, BOUND):
        yield node, caller
    node.destroy_node()
    caller.try_shutdown()
    ctx.try_shutdown()


def _set(caller, name, value):
    from uh_runtime import messages
    from uh_runtime.dds.services import ServiceClient, value_message
    client = ServiceClient(caller, 'rcl_interfaces/srv/SetParameters', '/uh3/controller/set_parameters')
    assert client.wait_for_service(BOUND)
    param = messages.dds_message('rcl_interfaces/msg/Parameter')(name=name, value=value_message(value))
    return client.call(client.request(parameters=[param]), BOUND).results[0]


def test_params_file_overrides_the_scenario_gains(controller):
    node, _ = controller
    assert node.get_parameter('outer.k').value == 1.3 and node.controller.gains.outer.k == 1.3
    paper = ControllerGains.from_mapping(load_scenario('paper').gains)
    assert node.controller.gains.inner == paper.inner and node.controller.gains.beta == paper.beta
    d = node.describe_parameter('outer.k')
    assert 'error gain' in d.description and d.floating_point_range[0].from_value == 0.0


def test_a_live_gain_change_is_validated_applied_and_logged(controller, capfd):
    node, caller = controller
    before = node.controller._params.copy()
    ok = _set(caller, 'outer.k', 1.2)
    assert ok.successful and node.get_parameter('outer.k').value == 1.2
    assert node.controller.gains.outer.k == 1.2
    assert not (node.controller._params == before).all()       # the kernel's parameters follow
    assert 'gains changed: outer.k = 1.2' in capfd.readouterr().err
    # rejected by the gains file's own checks, with its reason; the old value stays
    zero = _set(caller, 'outer.k', 0.0)
    assert not zero.successful and 'k must be > 0' in zero.reason
    tilt = _set(caller, 'tilt_limit_deg', 95.0)
    assert not tilt.successful and 'tilt_limit_deg must be < 90' in tilt.reason
    nodes = _set(caller, 'outer.rbf_nodes', 5)
    assert not nodes.successful and 'read-only' in nodes.reason
    assert node.get_parameter('outer.k').value == 1.2 and node.controller.gains.outer.k == 1.2
    assert math.isclose(node.controller.gains.tilt_limit, math.radians(30.0))
    assert 'rejected' in capfd.readouterr().err


@pytest.mark.dds
def test_a_new_controller_node_has_loaded_every_kernel_it_steps_with(domain_id):
    """The law's and the fault isolator's kernels are loaded while the node is built, not at its first step.

    A kernel first called mid-run is loaded then (0.05-0.4 s): a late step. Checked in a fresh process, where
    nothing else has called a kernel before.
    """
    import subprocess
    import sys
    probe = ("from uh_runtime import dds as rt\n"
             "from uh_controller_node.controller_node import ControllerNode\n"
             "from uh_controller_node import control_kernels as C, isolation_kernels as K\n"
             "ctx = rt.Context()\nctx.init(args=['probe'])\n"
             "node = ControllerNode(context=ctx, cli_args=['--ros-args', '-r', '__ns:=/uh3', '-p', 'uh_id:=3'])\n"
             "print(len(C.uh_control_step.signatures), len(K.isolation_step.signatures),"
             " len(K.isolation_status.signatures))\n"
             "node.destroy_node()\nctx.try_shutdown()\n")
    done = subprocess.run([sys.executable, '-P', '-c', probe], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert [int(n) for n in done.stdout.split()] == [1, 1, 1], done.stdout
