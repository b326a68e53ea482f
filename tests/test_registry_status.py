"""A controller status field is its line in ControllerStatus.msg plus one ``StatusField`` of uh_core.layout.

The status record ``ControllerStatusData`` (its fields, their order and its reader) and the wire
conversion follow ``STATUS_FIELDS``; a field declared in copies of the layout and the ``.msg`` reaches
the record and the message.
"""
import ast
import dataclasses
import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from uh_controller_node import controller
from uh_controller_node.controller import ControllerStatusData
from uh_core import layout

ROOT = Path(__file__).resolve().parents[1]
MSG = ROOT / 'uh_msgs' / 'msg' / 'ControllerStatus.msg'


def _msg_fields(text: str) -> list:
    """``(type, name)`` of the fields of a ``.msg`` text, in order (constants and comments left out)."""
    return [tuple(words) for line in text.splitlines() if len(words := line.split('#', 1)[0].split()) == 2]


def test_the_status_fields_are_the_msg_fields_from_z1_to_cost_rate():
    fields = _msg_fields(MSG.read_text())
    first = fields.index((layout.STATUS_FIELDS[0].kind, layout.STATUS_FIELDS[0].name))
    assert fields[first:first + len(layout.STATUS_FIELDS)] == [(f.kind, f.name) for f in layout.STATUS_FIELDS]
    assert layout.STATUS_LAYOUT == tuple((f.name, f.kind) for f in layout.STATUS_FIELDS)
    assert all(f.description and f.kind in layout.STATUS_WIDTH for f in layout.STATUS_FIELDS)


def test_the_record_s_fields_are_the_status_fields():
    fields = dataclasses.fields(ControllerStatusData)
    names = [f.name for f in fields]
    assert names == ['uh_id', 'step', 'stamp', *(f.name for f in layout.STATUS_FIELDS), 'stale_neighbours',
                     'isolation', 'lost_uhs', 'role']
    kinds = {layout.STATUS_VECTOR3: np.ndarray, layout.STATUS_FLOAT: float, layout.STATUS_FLAG: bool}
    assert [f.type for f in fields[3:-4]] == [kinds[f.kind] for f in layout.STATUS_FIELDS]
    assert all(f'{f.name} : ' in ControllerStatusData.__doc__ for f in layout.STATUS_FIELDS)


def _read_by_hand(status: np.ndarray) -> dict:
    """Give the record's fields as a reader written out field by field would."""
    values = status.tolist()
    out = {}
    for f in layout.STATUS_FIELDS:
        i = layout.STATUS_INDEX[f.name]
        if f.kind == layout.STATUS_VECTOR3:
            out[f.name] = status[i:i + 3]
        else:
            out[f.name] = values[i] != 0.0 if f.kind == layout.STATUS_FLAG else values[i]
    return out


def test_the_reader_gives_each_field_its_entries_and_type_views_included():
    rng = np.random.default_rng(7)
    for _ in range(50):
        status = rng.normal(size=layout.STATUS_SIZE)
        for name in layout.SATURATION_FLAGS:
            status[layout.STATUS_INDEX[name]] = rng.choice([0.0, 1.0, -0.0, math.nan])
        record = ControllerStatusData.from_vector(3, 4, 0.04, status)
        assert (record.uh_id, record.step, record.stamp) == (3, 4, 0.04)
        for name, expected in _read_by_hand(status).items():
            value = getattr(record, name)
            if isinstance(expected, np.ndarray):
                assert value.base is status and value.shape == (3,)
                assert np.array_equal(value, expected, equal_nan=True), name
            else:
                assert type(value) is type(expected), name
                assert value == expected or (math.isnan(value) and math.isnan(expected)), name
        assert record.saturated is any(getattr(record, name) for name in layout.SATURATION_FLAGS)


def test_the_reader_is_plain_code():
    tree = ast.parse(Path(controller.__file__).read_text())
    calls = {node.func.id for node in ast.walk(tree) if isinstance(node, ast.Call) and isinstance(node.func, ast.Name)}
    assert not calls & {'exec', 'eval', 'compile'}


_DUMMY_PROBE = r'''
import json
import numpy as np
from uh_core import layout
from uh_controller_node.controller import ControllerStatusData
from uh_wire import wire
names = [f.name for f in __import__('dataclasses').fields(ControllerStatusData)]
status = np.arange(layout.STATUS_SIZE, dtype=float)
record = ControllerStatusData.from_vector(1, 2, 0.5, status)
msg = wire.status_to_msg(1, 2, 0.5, record)
print(json.dumps(dict(layout=layout.__file__, size=layout.STATUS_SIZE, fields=names, record=record.dummy_status,
                      message=msg.dummy_status, cost_rate=msg.cost_rate)))
'''


def test_a_status_field_declared_once_reaches_the_record_and_the_message(tmp_path):
    for package in ('uh_core', 'uh_controller_node'):
        shutil.copytree(ROOT / package / package, tmp_path / package,
                        ignore=shutil.ignore_patterns('__pycache__', '*.so'))
    source = (tmp_path / 'uh_core' / 'layout.py').read_text()
    end = next(node.end_lineno for node in ast.parse(source).body
               if isinstance(node, ast.Assign) and any(getattr(t, 'id', '') == 'STATUS_FIELDS' for t in node.targets))
    lines = source.splitlines(keepends=True)
    lines.insert(end - 1, "    StatusField('dummy_status', STATUS_FLOAT, 'a field declared by a test'),\n")
    (tmp_path / 'uh_core' / 'layout.py').write_text(''.join(lines))
    shutil.copytree(MSG.parent, tmp_path / 'msg')
    text = MSG.read_text()
    cost_rate = next(line for line in text.splitlines(keepends=True) if line.startswith('float64 cost_rate '))
    (tmp_path / 'msg' / MSG.name).write_text(text.replace(cost_rate, cost_rate + 'float64 dummy_status\n', 1))
    env = dict(os.environ, PYTHONPATH=str(tmp_path), UH_MSGS_DIR=str(tmp_path / 'msg'),
               NUMBA_CACHE_DIR=str(tmp_path / 'numba'), UH_CACHE_DIR=str(tmp_path / 'cache'))
    done = subprocess.run([sys.executable, '-P', '-c', _DUMMY_PROBE], env=env, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout)
    assert out['layout'] == str(tmp_path / 'uh_core' / 'layout.py')
    assert out['size'] == layout.STATUS_SIZE + 1
    assert out['fields'][3 + len(layout.STATUS_FIELDS)] == 'dummy_status'
    assert out['record'] == out['message'] == layout.STATUS_SIZE            # its entry: the last one
    assert out['cost_rate'] == layout.STATUS_INDEX['cost_rate']
