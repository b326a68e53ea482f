"""Arrays and metrics of a recorded run, read with rosbags (an independent reader of the bag).

:func:`read_team_bag` turns the per-step topics of a bag into arrays indexed by step and UH (in
``scenario.ids`` order), the same layout as the in-process reference simulation's
``timeseries.npz``; :func:`write_metrics_from_bag` computes ``metrics.json`` from them with the one
metrics module (:mod:`uh_team.metrics`).

A bag that cannot be read raises :class:`BagContentError` saying which file and why: no such
directory, a file instead of a bag directory, no ``metadata.yaml``, a file that is not MCAP, an MCAP
file cut short (a recorder killed with SIGKILL: ``python -m uh_runtime.bag recover DIR`` restores it
up to its last complete chunk), a message that does not decode. Messages a receiver would have
rejected (non-finite values, another UH's id on a UH's topic) are left out like the nodes leave
them out, and counted in ``rejected``.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

__all__ = ['BagContentError', 'read_team_bag', 'write_metrics_from_bag']


class BagContentError(ValueError):
    """The bag is unreadable or lacks data the metrics need; the message names the file and topic."""


def _vec(v) -> list:
    return [v.x, v.y, v.z]


def read_team_bag(bag_dir, scenario) -> dict:
    """Read the per-step topics of a team bag into arrays.

    Returns a dict with ``time`` (K+1,), ``states`` (K+1, n, 12), ``commands`` (K+1, n, 4),
    ``reference`` (K+1, 5) = (x0, y0, z0, psi0, psi0'), ``fault_true_p``/``fault_true_w`` and
    ``fault_est_p``/``fault_est_w`` (K+1, n, 3), ``u_p`` (K+1, n, 3), ``saturated`` (K+1, n) (any
    saturation flag), ``isolation`` (the last fault isolation each controller published,
    :func:`_isolation_of`; ``{}`` when no status carried one), ``counts`` ({topic: messages}).
    Steps missing from a topic are NaN.
    """
    from rosbags.rosbag2 import Reader
    from rosbags.rosbag2.errors import ReaderError

    from uh_wire import topics
    from uh_runtime.messages import typestore

    bag_dir = Path(bag_dir)
    ids = list(scenario.ids)
    col = {i: c for c, i in enumerate(ids)}
    store = typestore()
    _check_bag_dir(bag_dir)
    try:
        reader = Reader(bag_dir)
        reader.open()
    except (ReaderError, OSError) as exc:
        raise BagContentError(f'cannot open bag {bag_dir}: {str(exc).rstrip(".")}{_diagnose_mcap(bag_dir)}') from None
    try:
        rows = {}
        try:
            for conn, _, raw in reader.messages():
                rows.setdefault(conn.topic, []).append((conn.msgtype, raw))
        except Exception as exc:  # rosbags raises several types for damaged chunks
            raise BagContentError(f'cannot read bag {bag_dir}: {str(exc).rstrip(".")}{_diagnose_mcap(bag_dir)}') from None
        counts = {c.topic: c.msgcount for c in reader.connections}
    finally:
        reader.close()
    rejected: dict = {}

    def decode(topic, msgtype, raw):
        try:
            return store.deserialize_cdr(raw, msgtype)
        except Exception as exc:
            raise BagContentError(f'bag {bag_dir}: a {msgtype} message on {topic} does not decode: {exc}') from None

    def valid(topic, msg, values, uh_id=None) -> bool:
        ok = np.isfinite(np.asarray(values, dtype=float)).all() and (uh_id is None or int(msg.uh_id) == uh_id)
        if not ok:
            rejected[topic] = rejected.get(topic, 0) + 1
        return bool(ok)

    steps = [decode(topics.REFERENCE.name, t, raw).step for t, raw in rows.get(topics.REFERENCE.name, [])]
    if not steps:
        raise BagContentError(f'bag {bag_dir} has no {topics.REFERENCE.name} messages: not a team run')
    K = max(steps)
    n = len(ids)
    nan = lambda *shape: np.full(shape, np.nan)
    out = {'time': np.arange(K + 1) * scenario.dt, 'states': nan(K + 1, n, 12), 'commands': nan(K + 1, n, 4),
           'reference': nan(K + 1, 5), 'fault_true_p': nan(K + 1, n, 3), 'fault_true_w': nan(K + 1, n, 3),
           'fault_est_p': nan(K + 1, n, 3), 'fault_est_w': nan(K + 1, n, 3), 'u_p': nan(K + 1, n, 3),
           'saturated': np.zeros((K + 1, n), dtype=bool), 'isolation': {}, 'counts': counts,
           'rejected': rejected}
    name = topics.REFERENCE.name
    for msgtype, raw in rows.get(name, []):
        r = decode(name, msgtype, raw)
        row = [*_vec(r.position), r.yaw, r.yaw_rate]
        if valid(name, r, row + _vec(r.velocity) + _vec(r.acceleration)):
            out['reference'][r.step] = row
    for i in ids:
        c = col[i]
        name = topics.uh_topic(i, topics.STATE)
        for msgtype, raw in rows.get(name, []):
            s = decode(name, msgtype, raw)
            row = _vec(s.position) + _vec(s.velocity) + _vec(s.euler) + _vec(s.body_rates)
            if s.step <= K and valid(name, s, row, i):
                out['states'][s.step, c] = row
        name = topics.uh_topic(i, topics.COMMAND)
        for msgtype, raw in rows.get(name, []):
            u = decode(name, msgtype, raw)
            row = [u.theta_col, u.theta_tr, u.delta_lat, u.delta_lon]
            if u.step <= K and valid(name, u, row, i):
                out['commands'][u.step, c] = row
        name = topics.uh_topic(i, topics.FAULT_TRUTH)
        for msgtype, raw in rows.get(name, []):
            f = decode(name, msgtype, raw)
            if f.step <= K and valid(name, f, _vec(f.lumped_fault_position) + _vec(f.lumped_fault_attitude), i):
                out['fault_true_p'][f.step, c] = _vec(f.lumped_fault_position)
                out['fault_true_w'][f.step, c] = _vec(f.lumped_fault_attitude)
        name = topics.uh_topic(i, topics.STATUS)
        last = None
        for msgtype, raw in rows.get(name, []):
            st = decode(name, msgtype, raw)
            if st.step <= K and st.uh_id == i:
                if last is None or st.step >= last.step:
                    last = st
                out['fault_est_p'][st.step, c] = _vec(st.fault_estimate_position)
                out['fault_est_w'][st.step, c] = _vec(st.fault_estimate_attitude)
                out['u_p'][st.step, c] = _vec(st.u_p)
                out['saturated'][st.step, c] = st.saturated_tilt or st.saturated_collective or st.saturated_cyclic
        if last is not None:
            out['isolation'][i] = _isolation_of(last)
    return out


def _isolation_of(status) -> dict:
    """The fault isolation fields of one ``ControllerStatus`` as plain lists (one entry per channel):
    ``step``, ``isolated``, ``detection_time`` (s), ``effectiveness``, ``bias`` (rad),
    ``identification`` (codes).
    """
    return {'step': int(status.step), 'isolated': [bool(v) for v in status.fault_isolated],
            'detection_time': [float(v) for v in status.fault_detection_time],
            'effectiveness': [float(v) for v in status.identified_effectiveness],
            'bias': [float(v) for v in status.identified_bias],
            'identification': [int(v) for v in status.fault_identification]}


def _check_bag_dir(bag_dir: Path) -> None:
    """Raise BagContentError for the ways a path can fail to be a bag before rosbags tries it."""
    if not bag_dir.exists():
        raise BagContentError(f'cannot open bag {bag_dir}: no such directory')
    if not bag_dir.is_dir():
        raise BagContentError(f'cannot open bag {bag_dir}: it is a file; give the bag directory (the one '
                              'holding metadata.yaml and the .mcap file)')
    if not (bag_dir / 'metadata.yaml').is_file():
        raise BagContentError(f'cannot open bag {bag_dir}: it has no metadata.yaml (not a rosbag2 bag, or its '
                              f'recorder did not finish it){_diagnose_mcap(bag_dir)}')


def _diagnose_mcap(bag_dir: Path) -> str:
    """What is wrong with the bag's MCAP file, as a sentence to append to an error (or '')."""
    from uh_runtime.bag_reader import BagError, bag_file, read_messages
    try:
        result = read_messages(bag_file(bag_dir))
    except BagError as exc:
        return f'; {exc}'
    if result.complete:
        return ''
    return (f'; its MCAP file {result.path.name} is cut short or damaged after {result.good_bytes} of '
            f'{result.file_bytes} bytes ({result.problem}), as a recorder killed mid-run leaves it: '
            f'`python -m uh_runtime.bag recover {bag_dir}` restores it up to its last complete chunk')


def write_metrics_from_bag(bag_dir, scenario, case: str, out_path, wall_time_s: float | None = None) -> dict:
    """Compute the metrics of docs/metrics.md from a team bag and write them to ``out_path`` (JSON)."""
    from uh_team.metrics import metrics_from_arrays

    arrays = read_team_bag(bag_dir, scenario)
    metrics = metrics_from_arrays(arrays, scenario, case, wall_time_s=wall_time_s)
    Path(out_path).write_text(json.dumps(metrics, indent=2, sort_keys=False) + '\n')
    return metrics
