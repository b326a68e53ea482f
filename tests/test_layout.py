"""The layouts of uh_core.layout agree with the message definitions and the kernels that use them."""
import ast
import re
from pathlib import Path

from uh_core import layout

ROOT = Path(__file__).resolve().parents[1]


def test_channel_order_is_the_one_of_actuator_fault_msg():
    text = (ROOT / 'uh_msgs' / 'msg' / 'ActuatorFault.msg').read_text()
    constants = {name.lower(): int(value) for name, value in re.findall(r'uint8 CHANNEL_(\w+) = (\d+)', text)}
    assert constants == {name: i for i, name in enumerate(layout.CHANNEL_NAMES)}
    assert [layout.U_COL, layout.U_TR, layout.U_LAT, layout.U_LON] == list(range(layout.NUM_CHANNELS))


def test_command_msg_fields_follow_the_input_order():
    text = (ROOT / 'uh_msgs' / 'msg' / 'ActuatorCommand.msg').read_text()
    fields = re.findall(r'^float64 (\w+)', text, flags=re.M)
    assert fields == list(layout.INPUT_NAMES)


def test_every_alias_names_its_channel():
    assert layout.CHANNEL_ALIASES['collective'] == layout.CHANNEL_ALIASES['theta_col'] == layout.U_COL
    assert layout.CHANNEL_ALIASES['tail_rotor'] == layout.CHANNEL_ALIASES['theta_tr'] == layout.U_TR
    assert layout.CHANNEL_ALIASES['lateral'] == layout.CHANNEL_ALIASES['delta_lat'] == layout.U_LAT
    assert layout.CHANNEL_ALIASES['longitudinal'] == layout.CHANNEL_ALIASES['delta_lon'] == layout.U_LON


def test_state_blocks_tile_the_state_vector():
    starts = [layout.X_P, layout.X_V, layout.X_THETA, layout.X_OMEGA]
    assert starts == list(range(0, layout.STATE_SIZE, 3))
    assert [layout.R_P, layout.R_V, layout.R_YAW + 1] == [0, 3, layout.REFERENCE_SIZE]


def test_the_layout_has_one_home():
    """No other module of the packages assigns a layout constant of its own (they import uh_core.layout)."""
    import ast
    names = set(layout.__all__) - {'Reference'}
    offenders = []
    for pkg in ('uh_core', 'uh_topology', 'uh_wire', 'uh_sim_node', 'uh_controller_node', 'uh_team', 'uh_report',
                'uh_campaign', 'uh_bringup', 'uh_security'):
        for path in (ROOT / pkg / pkg).rglob('*.py'):
            if path.name == 'layout.py':
                continue
            for node in ast.parse(path.read_text()).body:
                targets = node.targets if isinstance(node, ast.Assign) else []
                for target in targets:
                    elts = target.elts if isinstance(target, ast.Tuple) else [target]
                    offenders += [f'{path.relative_to(ROOT)}: {e.id}' for e in elts
                                  if isinstance(e, ast.Name) and e.id in names]
    assert not offenders


def _status_msg_fields():
    """``(type, name)`` of the fields of ControllerStatus.msg, in order (constants and comments left out)."""
    text = (ROOT / 'uh_msgs' / 'msg' / 'ControllerStatus.msg').read_text()
    fields = []
    for line in text.splitlines():
        words = line.split('#', 1)[0].split()
        if len(words) == 2:        # "type name"; a constant is "type NAME = value"
            fields.append((words[0], words[1]))
    return fields


def test_status_layout_is_the_controller_status_msg_from_z1_to_cost_rate():
    fields = _status_msg_fields()
    names = [name for _, name in fields]
    first = names.index(layout.STATUS_LAYOUT[0][0])
    assert fields[first:first + len(layout.STATUS_LAYOUT)] == [(kind, name) for name, kind in layout.STATUS_LAYOUT]
    assert names[:first] == ['header', 'uh_id', 'step']
    assert names[first + len(layout.STATUS_LAYOUT)] == 'stale_neighbours'


def test_status_indices_tile_the_status_vector_in_layout_order():
    starts = [layout.STATUS_INDEX[name] for name, _ in layout.STATUS_LAYOUT]
    widths = [layout.STATUS_WIDTH[kind] for _, kind in layout.STATUS_LAYOUT]
    assert starts == [sum(widths[:i]) for i in range(len(widths))]
    assert layout.STATUS_SIZE == sum(widths)
    assert 3 * layout.STATUS_VECTORS == layout.STATUS_INDEX[layout.STATUS_LAYOUT[layout.STATUS_VECTORS][0]]
    constants = {name: getattr(layout, name) for name in layout.__all__ if name.startswith('S_')}
    assert sorted(constants.values()) == starts     # one S_* per field, none left over


def test_status_record_and_wire_follow_the_status_layout():
    import dataclasses

    import numpy as np

    from uh_controller_node.controller import ControllerStatusData
    from uh_wire import wire

    record_fields = [f.name for f in dataclasses.fields(ControllerStatusData)]
    assert record_fields[3:3 + len(layout.STATUS_LAYOUT)] == [name for name, _ in layout.STATUS_LAYOUT]
    status = np.arange(layout.STATUS_SIZE, dtype=float)
    record = ControllerStatusData.from_vector(1, 2, 0.5, status)
    msg = wire.status_to_msg(1, 2, 0.5, record)
    for name, kind in layout.STATUS_LAYOUT:
        i = layout.STATUS_INDEX[name]
        value = getattr(msg, name)
        if kind == layout.STATUS_VECTOR3:
            assert [value.x, value.y, value.z] == [i, i + 1, i + 2]
        elif kind == layout.STATUS_FLAG:
            assert value is (i != 0.0)
        else:
            assert value == i


def test_no_module_defines_its_own_status_index():
    """The status vector's indices and field lists live in uh_core.layout only."""
    import ast
    offenders = []
    for pkg in ('uh_core', 'uh_wire', 'uh_sim_node', 'uh_controller_node', 'uh_team', 'uh_report'):
        for path in (ROOT / pkg / pkg).rglob('*.py'):
            if path.name == 'layout.py':
                continue
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.Assign):
                    for target in node.targets:
                        for e in (target.elts if isinstance(target, ast.Tuple) else [target]):
                            if isinstance(e, ast.Name) and re.fullmatch(r'S_[A-Z0-9_]+', e.id):
                                offenders.append(f'{path.relative_to(ROOT)}: {e.id}')
                # a literal list of status field names (as wire.py once had) instead of STATUS_LAYOUT
                if isinstance(node, ast.Tuple) and len(node.elts) > 2 and all(
                        isinstance(e, ast.Constant) and e.value in layout.STATUS_INDEX for e in node.elts):
                    offenders.append(f'{path.relative_to(ROOT)}:{node.lineno}: a literal list of status fields')
    assert not offenders


def test_team_kernel_takes_its_arrays_in_groups():
    """run_team_steps takes the team's arrays as a few namedtuples, not one argument per array."""
    import inspect

    from uh_team import team_kernel
    params = list(inspect.signature(team_kernel.run_team_steps.py_func).parameters)
    assert params == ['k0', 'k1', 'last', 'dt', 'references', 'team', 'links_impaired', 'live', 'record']
    assert team_kernel.TeamArrays._fields == ('config', 'impairments', 'state')


def test_kernel_parameter_indices_have_one_home_each():
    """CP_* and L_* are assigned only in control_kernels.py, P_* only in plant_kernels.py, each from its table."""
    import ast
    homes = {'CP_': 'control_kernels.py', 'L_': 'control_kernels.py', 'P_': 'plant_kernels.py'}
    offenders = []
    for pkg in ('uh_core', 'uh_wire', 'uh_sim_node', 'uh_controller_node', 'uh_team', 'uh_report'):
        for path in (ROOT / pkg / pkg).rglob('*.py'):
            for node in ast.parse(path.read_text()).body:
                for target in (node.targets if isinstance(node, ast.Assign) else []):
                    for e in (target.elts if isinstance(target, ast.Tuple) else [target]):
                        prefix = next((p for p in homes if isinstance(e, ast.Name) and e.id.startswith(p)
                                       and e.id[len(p):].isupper()), None)
                        if prefix and path.name != homes[prefix]:
                            offenders.append(f'{path.relative_to(ROOT)}: {e.id}')
    assert not offenders


def test_parameter_tables_tile_the_parameter_vectors():
    from uh_controller_node import control_kernels as ck
    from uh_sim_node import plant_kernels as pk
    model = sum(count for _, count in ck.MODEL_ENTRIES)
    assert list(ck.GAIN_INDEX.values()) == list(range(model, ck.CP_OUTER))
    assert list(ck.LOOP_GAIN_OFFSET.values()) == list(range(ck.LOOP_GAINS_SIZE))
    assert ck.CONTROL_PARAMS_SIZE == ck.CP_OUTER + 2 * ck.LOOP_GAINS_SIZE
    assert pk.PARAMS_SIZE == pk.PARAMS_INDEX['input_upper'] + layout.INPUT_SIZE


#: The names uh_runtime puts on the wire (uh_runtime/names.py): the DDS prefixes of ROS topics and
#: services and the recorder's progress topic.
_WIRE_NAMES = ('rt', 'rq', 'rr', '/recorder/progress')


def _package_modules():
    for pkg in sorted(p.name for p in ROOT.glob('uh_*') if (p / p.name).is_dir() and p.name != 'uh_msgs'):
        yield from sorted((ROOT / pkg / pkg).rglob('*.py'))
    yield from sorted((ROOT / 'uh_bringup' / 'launch').glob('*.py'))


def _code_strings(tree):
    """Yield the string constants of ``tree`` that are not docstrings."""
    docstrings = {id(body[0].value) for node in ast.walk(tree)
                  if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                  for body in [node.body] if body and isinstance(body[0], ast.Expr)}
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
            yield node


def test_the_wire_names_have_one_home():
    """Check that the DDS prefixes and the progress topic are spelt out only in uh_runtime/names.py."""
    offenders = []
    for path in _package_modules():
        if path.name == 'names.py':
            continue
        for node in _code_strings(ast.parse(path.read_text())):
            value = node.value
            if value in _WIRE_NAMES or value.startswith(('rt/', 'rq/', 'rr/')):
                # scheduling.py names the scheduling policies of Linux, whose SCHED_RR is 'rr'
                if not (path.name == 'scheduling.py' and value == 'rr'):
                    offenders.append(f'{path.relative_to(ROOT)}:{node.lineno}: {value!r}')
    assert not offenders


def test_the_default_stale_timeout_has_one_home():
    """Check that no module but uh_wire/run_config.py gives ``stale_timeout`` a literal default."""
    offenders = []
    for path in _package_modules():
        if path.name == 'run_config.py':
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            pairs = []
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                args = node.args.posonlyargs + node.args.args
                pairs += zip([a.arg for a in args[len(args) - len(node.args.defaults):]], node.args.defaults,
                             strict=True)
                pairs += [(a.arg, d) for a, d in zip(node.args.kwonlyargs, node.args.kw_defaults, strict=True)
                          if d is not None]
            elif isinstance(node, ast.Call):
                pairs += [(k.arg, k.value) for k in node.keywords]
                if node.args and isinstance(node.args[0], ast.Constant) and len(node.args) > 1:
                    pairs.append((node.args[0].value, node.args[1]))   # declare_parameter('stale_timeout', 0.25)
            offenders += [f'{path.relative_to(ROOT)}:{value.lineno}' for name, value in pairs
                          if isinstance(name, str) and 'stale_timeout' in name and isinstance(value, ast.Constant)
                          and isinstance(value.value, (int, float, str)) and value.value is not None]
    assert not offenders
