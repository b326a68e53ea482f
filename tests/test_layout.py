"""The layouts of uh_core.layout agree with the message definitions and the kernels that use them."""
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
                'uh_campaign', 'uh_bringup'):
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
