"""Arrays and metrics of a recorded run, read with rosbags (an independent reader of the bag).

:func:`read_team_bag` turns the per-step topics of a bag into arrays indexed by step and UH (in
``scenario.ids`` order), the same layout as the in-process reference simulation's
``timeseries.npz``; :func:`write_metrics_from_bag` computes ``metrics.json`` from them with the one
metrics module (:mod:`uh_controller_node.metrics`).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

__all__ = ['BagContentError', 'read_team_bag', 'write_metrics_from_bag']


class BagContentError(ValueError):
    """The bag is unreadable or lacks data the metrics need; the message names the file and topic."""


def _typestore():
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    from uh_runtime.bag import _msg_directory
    store = get_typestore(Stores.ROS2_JAZZY)
    for path in sorted(_msg_directory().glob('*.msg')):
        store.register(get_types_from_msg(path.read_text(), f'uh_msgs/msg/{path.stem}'))
    return store


def _vec(v) -> list:
    return [v.x, v.y, v.z]


def read_team_bag(bag_dir, scenario) -> dict:
    """Read the per-step topics of a team bag into arrays.

    Returns a dict with ``time`` (K+1,), ``states`` (K+1, n, 12), ``commands`` (K+1, n, 4),
    ``reference`` (K+1, 5) = (x0, y0, z0, psi0, psi0'), ``fault_true_p``/``fault_true_w`` and
    ``fault_est_p``/``fault_est_w`` (K+1, n, 3), ``u_p`` (K+1, n, 3), ``saturated`` (K+1, n) (any
    saturation flag), ``counts`` ({topic: messages}). Steps missing from a topic are NaN.
    """
    from rosbags.rosbag2 import Reader
    from rosbags.rosbag2.errors import ReaderError

    from uh_topology import topics

    bag_dir = Path(bag_dir)
    ids = list(scenario.ids)
    col = {i: c for c, i in enumerate(ids)}
    store = _typestore()
    try:
        reader = Reader(bag_dir)
        reader.open()
    except (ReaderError, OSError) as exc:
        raise BagContentError(f'cannot open bag {bag_dir}: {exc}') from None
    try:
        rows = {}
        for conn, _, raw in reader.messages():
            rows.setdefault(conn.topic, []).append((conn.msgtype, raw))
        counts = {c.topic: c.msgcount for c in reader.connections}
    finally:
        reader.close()
    steps = [store.deserialize_cdr(raw, t).step for t, raw in rows.get(topics.REFERENCE.name, [])]
    if not steps:
        raise BagContentError(f'bag {bag_dir} has no {topics.REFERENCE.name} messages: not a team run')
    K = max(steps)
    n = len(ids)
    nan = lambda *shape: np.full(shape, np.nan)
    out = {'time': np.arange(K + 1) * scenario.dt, 'states': nan(K + 1, n, 12), 'commands': nan(K + 1, n, 4),
           'reference': nan(K + 1, 5), 'fault_true_p': nan(K + 1, n, 3), 'fault_true_w': nan(K + 1, n, 3),
           'fault_est_p': nan(K + 1, n, 3), 'fault_est_w': nan(K + 1, n, 3), 'u_p': nan(K + 1, n, 3),
           'saturated': np.zeros((K + 1, n), dtype=bool), 'counts': counts}
    for msgtype, raw in rows.get(topics.REFERENCE.name, []):
        r = store.deserialize_cdr(raw, msgtype)
        out['reference'][r.step] = [*_vec(r.position), r.yaw, r.yaw_rate]
    for i in ids:
        c = col[i]
        for msgtype, raw in rows.get(topics.uh_topic(i, topics.STATE), []):
            s = store.deserialize_cdr(raw, msgtype)
            if s.step <= K:
                out['states'][s.step, c] = _vec(s.position) + _vec(s.velocity) + _vec(s.euler) + _vec(s.body_rates)
        for msgtype, raw in rows.get(topics.uh_topic(i, topics.COMMAND), []):
            u = store.deserialize_cdr(raw, msgtype)
            if u.step <= K:
                out['commands'][u.step, c] = [u.theta_col, u.theta_tr, u.delta_lat, u.delta_lon]
        for msgtype, raw in rows.get(topics.uh_topic(i, topics.FAULT_TRUTH), []):
            f = store.deserialize_cdr(raw, msgtype)
            if f.step <= K:
                out['fault_true_p'][f.step, c] = _vec(f.lumped_fault_position)
                out['fault_true_w'][f.step, c] = _vec(f.lumped_fault_attitude)
        for msgtype, raw in rows.get(topics.uh_topic(i, topics.STATUS), []):
            st = store.deserialize_cdr(raw, msgtype)
            if st.step <= K:
                out['fault_est_p'][st.step, c] = _vec(st.fault_estimate_position)
                out['fault_est_w'][st.step, c] = _vec(st.fault_estimate_attitude)
                out['u_p'][st.step, c] = _vec(st.u_p)
                out['saturated'][st.step, c] = st.saturated_tilt or st.saturated_collective or st.saturated_cyclic
    return out


def write_metrics_from_bag(bag_dir, scenario, case: str, out_path, wall_time_s: float | None = None) -> dict:
    """Compute the metrics of DESIGN.md 2.8 from a team bag and write them to ``out_path`` (JSON)."""
    from uh_controller_node.metrics import metrics_from_arrays

    arrays = read_team_bag(bag_dir, scenario)
    metrics = metrics_from_arrays(arrays, scenario, case, wall_time_s=wall_time_s)
    Path(out_path).write_text(json.dumps(metrics, indent=2, sort_keys=False) + '\n')
    return metrics
