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
from rosbags.rosbag2 import Reader
from rosbags.rosbag2.errors import ReaderError

from uh_runtime.bag_reader import BagError, bag_file, read_messages
from uh_runtime.messages import typestore
from uh_team.metrics import metrics_from_arrays
from uh_team.run_arrays import new_run_arrays
from uh_wire import topics

__all__ = ['BagContentError', 'read_team_bag', 'write_metrics_from_bag']


class BagContentError(ValueError):
    """The bag is unreadable or lacks data the metrics need; the message names the file and topic."""


def _vec(v) -> list:
    return [v.x, v.y, v.z]


class _Decoder:
    """Decodes the raw messages of one bag and counts, per topic, those a receiver would reject."""

    def __init__(self, bag_dir: Path):
        self.bag_dir = bag_dir
        self.store = typestore()
        self.rejected: dict = {}

    def decode(self, topic: str, msgtype: str, raw):
        """Return the message of ``raw``; a BagContentError if it does not decode."""
        try:
            return self.store.deserialize_cdr(raw, msgtype)
        except Exception as exc:
            raise BagContentError(f'bag {self.bag_dir}: a {msgtype} message on {topic} does not decode: '
                                  f'{exc}') from None

    def valid(self, topic: str, msg, values, uh_id=None) -> bool:
        """Tell whether ``values`` are finite and ``msg`` is of UH ``uh_id`` (if given); count it if not."""
        ok = np.isfinite(np.asarray(values, dtype=float)).all() and (uh_id is None or int(msg.uh_id) == uh_id)
        if not ok:
            self.rejected[topic] = self.rejected.get(topic, 0) + 1
        return bool(ok)


def _read_raw(bag_dir: Path) -> tuple[dict, dict]:
    """Return ``({topic: [(msgtype, raw bytes)]}, {topic: message count})`` of the bag in ``bag_dir``."""
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
            raise BagContentError(f'cannot read bag {bag_dir}: {str(exc).rstrip(".")}'
                                  f'{_diagnose_mcap(bag_dir)}') from None
        counts = {c.topic: c.msgcount for c in reader.connections}
    finally:
        reader.close()
    return rows, counts


def _fill_reference(out: dict, messages, dec: _Decoder) -> None:
    """Write the virtual leader's ``(x0, y0, z0, psi0, psi0')`` of each step into ``out['reference']``."""
    name = topics.REFERENCE.name
    for msgtype, raw in messages:
        r = dec.decode(name, msgtype, raw)
        row = [*_vec(r.position), r.yaw, r.yaw_rate]
        if dec.valid(name, r, row + _vec(r.velocity) + _vec(r.acceleration)):
            out['reference'][r.step] = row


def _fill_plant_side(out: dict, rows: dict, dec: _Decoder, uh: int, c: int, last_step: int) -> None:
    """Write UH ``uh``'s states, commands and true lumped faults into column ``c`` of ``out``."""
    name = topics.uh_topic(uh, topics.STATE)
    for msgtype, raw in rows.get(name, []):
        s = dec.decode(name, msgtype, raw)
        row = _vec(s.position) + _vec(s.velocity) + _vec(s.euler) + _vec(s.body_rates)
        if s.step <= last_step and dec.valid(name, s, row, uh):
            out['states'][s.step, c] = row
    name = topics.uh_topic(uh, topics.COMMAND)
    for msgtype, raw in rows.get(name, []):
        u = dec.decode(name, msgtype, raw)
        row = [u.theta_col, u.theta_tr, u.delta_lat, u.delta_lon]
        if u.step <= last_step and dec.valid(name, u, row, uh):
            out['commands'][u.step, c] = row
    name = topics.uh_topic(uh, topics.FAULT_TRUTH)
    for msgtype, raw in rows.get(name, []):
        f = dec.decode(name, msgtype, raw)
        if f.step <= last_step and dec.valid(name, f, _vec(f.lumped_fault_position) + _vec(f.lumped_fault_attitude),
                                             uh):
            out['fault_true_p'][f.step, c] = _vec(f.lumped_fault_position)
            out['fault_true_w'][f.step, c] = _vec(f.lumped_fault_attitude)


def _fill_status(out: dict, rows: dict, dec: _Decoder, uh: int, c: int, last_step: int) -> None:
    """Write UH ``uh``'s fault estimates, ``u_p`` and saturation into column ``c`` of ``out``.

    The fault isolation of its last status goes to ``out['isolation'][uh]``.
    """
    name = topics.uh_topic(uh, topics.STATUS)
    last = None
    for msgtype, raw in rows.get(name, []):
        st = dec.decode(name, msgtype, raw)
        if st.step <= last_step and st.uh_id == uh:
            if last is None or st.step >= last.step:
                last = st
            out['fault_est_p'][st.step, c] = _vec(st.fault_estimate_position)
            out['fault_est_w'][st.step, c] = _vec(st.fault_estimate_attitude)
            out['u_p'][st.step, c] = _vec(st.u_p)
            out['saturated'][st.step, c] = st.saturated_tilt or st.saturated_collective or st.saturated_cyclic
    if last is not None:
        out['isolation'][uh] = _isolation_of(last)


def read_team_bag(bag_dir, scenario) -> dict:
    """Read the per-step topics of a team bag into arrays.

    Returns a dict with ``time`` (K+1,), ``states`` (K+1, n, 12), ``commands`` (K+1, n, 4),
    ``reference`` (K+1, 5) = (x0, y0, z0, psi0, psi0'), ``fault_true_p``/``fault_true_w`` and
    ``fault_est_p``/``fault_est_w`` (K+1, n, 3), ``u_p`` (K+1, n, 3), ``saturated`` (K+1, n) (any
    saturation flag), ``isolation`` (the last fault isolation each controller published,
    :func:`_isolation_of`; ``{}`` when no status carried one), ``counts`` ({topic: messages}).
    Steps missing from a topic are NaN (the arrays of :func:`uh_team.run_arrays.new_run_arrays`).
    """
    bag_dir = Path(bag_dir)
    ids = list(scenario.ids)
    rows, counts = _read_raw(bag_dir)
    dec = _Decoder(bag_dir)
    reference = rows.get(topics.REFERENCE.name, [])
    steps = [dec.decode(topics.REFERENCE.name, t, raw).step for t, raw in reference]
    if not steps:
        raise BagContentError(f'bag {bag_dir} has no {topics.REFERENCE.name} messages: not a team run')
    K = max(steps)
    out = {'time': np.arange(K + 1) * scenario.dt, **new_run_arrays(K + 1, len(ids)), 'isolation': {},
           'counts': counts, 'rejected': dec.rejected}
    _fill_reference(out, reference, dec)
    for c, i in enumerate(ids):
        _fill_plant_side(out, rows, dec, i, c, K)
        _fill_status(out, rows, dec, i, c, K)
    return out


def _isolation_of(status) -> dict:
    """Return the fault isolation fields of one ``ControllerStatus`` as plain lists.

    One entry per channel: ``step``, ``isolated``, ``detection_time`` (s), ``effectiveness``, ``bias`` (rad),
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
    """Say what is wrong with the bag's MCAP file, as a sentence to append to an error (or '')."""
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
    arrays = read_team_bag(bag_dir, scenario)
    metrics = metrics_from_arrays(arrays, scenario, case, wall_time_s=wall_time_s)
    Path(out_path).write_text(json.dumps(metrics, indent=2, sort_keys=False) + '\n')
    return metrics
