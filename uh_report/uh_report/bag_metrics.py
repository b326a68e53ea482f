"""Arrays and metrics of a recorded run, from its bag.

:func:`read_team_bag` turns the per-step topics of a bag into arrays indexed by step and UH (in
``scenario.ids`` order), the same layout as the in-process reference simulation's
``timeseries.npz``; :func:`write_metrics_from_bag` computes ``metrics.json`` from them with the one
metrics module (:mod:`uh_team.metrics`). The MCAP records are read with the ``mcap`` library
(:func:`uh_runtime.bags.bag_reader.read_messages`, which checks every chunk); the messages are decoded
with rosbags' type store, the numeric fields of a topic all at once (:mod:`uh_report.cdr_columns`):
well under a second for the 126,000 messages of a 60 s paper run.

A bag that cannot be read raises :class:`BagContentError` saying which file and why: no such
directory, a file instead of a bag directory, no ``metadata.yaml``, a file that is not MCAP, an MCAP
file cut short (a recorder killed with SIGKILL: ``python -m uh_runtime.bags.bag recover DIR`` restores it
up to its last complete chunk), a message that does not decode. Messages a receiver would have
rejected (non-finite values, another UH's id on a UH's topic) are left out like the nodes leave
them out, and counted in ``rejected``.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from uh_core.layout import SATURATION_FLAGS
from uh_runtime.bags.bag_reader import BagError, bag_file, find_bag_files, read_messages
from uh_runtime.messages import typestore
from uh_team.metrics import metrics_from_arrays
from uh_team.run_arrays import new_run_arrays
from uh_wire import topics

from .cdr_columns import read_columns

__all__ = ['BagContentError', 'read_team_bag', 'write_metrics_from_bag']


class BagContentError(ValueError):
    """The bag is unreadable or lacks data the metrics need; the message names the file and topic."""


def _xyz(field: str) -> tuple:
    return (f'{field}.x', f'{field}.y', f'{field}.z')


# The numeric fields read from each per-step topic (cdr_columns names)
_STATE = _xyz('position') + _xyz('velocity') + _xyz('euler') + _xyz('body_rates')
_COMMAND = ('theta_col', 'theta_tr', 'delta_lat', 'delta_lon')
_FAULT_P, _FAULT_W = _xyz('lumped_fault_position'), _xyz('lumped_fault_attitude')
_REFERENCE = _xyz('position') + ('yaw', 'yaw_rate')
_REFERENCE_CHECKED = _xyz('velocity') + _xyz('acceleration')
_STATUS_P, _STATUS_W = _xyz('fault_estimate_position'), _xyz('fault_estimate_attitude')


class _TopicMessages:
    """The raw messages of one topic of a bag, in log-time order, and their type."""

    def __init__(self, msgtype: str):
        self.msgtype = msgtype
        self.log_times: list = []
        self.payloads: list = []

    def in_log_time_order(self) -> None:
        """Sort the messages by log time (a stable sort: file order among equal log times)."""
        order = np.argsort(np.asarray(self.log_times, dtype=np.int64), kind='stable')
        if (np.diff(order) != 1).any():
            self.payloads = [self.payloads[k] for k in order]
            self.log_times = [self.log_times[k] for k in order]


class _Bag:
    """The raw messages of a bag by topic; per-topic numeric columns; the messages a receiver would reject.

    ``rejected`` counts, per topic, the messages left out as a receiver leaves them out (non-finite
    values, another UH's id on a UH's topic).
    """

    def __init__(self, bag_dir: Path):
        self.bag_dir = bag_dir
        self.topics, self.counts, schemas = _read_raw(bag_dir)
        self.store = bag_typestore(schemas)
        self.rejected: dict = {}

    def columns(self, spec_name: str, expected_type: str, fields) -> dict | None:
        """Return ``{field: array}`` of ``step``, ``uh_id`` (if the type has it) and ``fields``; None if absent."""
        messages = self.topics.get(spec_name)
        if messages is None:
            return None
        if messages.msgtype != expected_type:
            raise BagContentError(f'bag {self.bag_dir}: topic {spec_name} has type {messages.msgtype}, '
                                  f'expected {expected_type}')
        has_id = any(name == 'uh_id' for name, _ in self.store.fielddefs[expected_type][1])
        names = ('step', *(('uh_id',) if has_id else ()), *fields)
        try:
            return read_columns(self.store, expected_type, messages.payloads, names)
        except Exception as exc:   # rosbags raises several types for a payload that does not decode
            raise BagContentError(f'bag {self.bag_dir}: a {expected_type} message on {spec_name} does not decode: '
                                  f'{exc}') from None

    def decode(self, spec_name: str, index: int):
        """Return message ``index`` (log-time order) of topic ``spec_name`` decoded by rosbags."""
        messages = self.topics[spec_name]
        return self.store.deserialize_cdr(messages.payloads[index], messages.msgtype)

    def keep(self, topic: str, ok: np.ndarray, considered: np.ndarray) -> np.ndarray:
        """Count the ``considered`` messages that are not ``ok`` as rejected; return ``ok & considered``."""
        bad = int((considered & ~ok).sum())
        if bad:
            self.rejected[topic] = self.rejected.get(topic, 0) + bad
        return ok & considered


def _stack(cols: dict, fields) -> np.ndarray:
    """Return the columns ``fields`` side by side as a float array (messages, fields)."""
    return np.stack([cols[f].astype(float) for f in fields], axis=1)


def _finite(values: np.ndarray) -> np.ndarray:
    return np.isfinite(values).all(axis=1)


def _last_per_step(steps: np.ndarray, take: np.ndarray) -> np.ndarray:
    """Return the indices of the taken messages, the last one of each step (as a receiver overwrites)."""
    index = np.flatnonzero(take)
    _, first_from_end = np.unique(steps[index][::-1], return_index=True)
    return index[len(index) - 1 - first_from_end]


def bag_typestore(schemas: dict):
    """Give the type store to decode a bag whose ``uh_msgs`` schemas are ``{type: ros2msg text}``.

    The project's store (:func:`uh_runtime.messages.typestore`) when every ``uh_msgs`` type the bag
    recorded is defined as now; otherwise a store with the bag's own definitions of those types, so
    that a bag recorded before a message gained a field (``UHState.lost_uhs``, docs/resilience.md)
    still reads: a field it lacks is simply not there.
    """
    store = typestore()
    older = {}
    for name, text in sorted(schemas.items()):
        if not name.startswith('uh_msgs/') or not text:
            continue
        try:
            parsed = get_types_from_msg(text, name)
        except Exception:    # rosbags raises several types for a definition it cannot parse: use ours
            continue
        if parsed[name] != store.fielddefs.get(name):
            older.update((key, value) for key, value in parsed.items() if key.startswith('uh_msgs/'))
    if not older:
        return store
    bag_store = get_typestore(Stores.EMPTY)
    bag_store.register(older)
    bag_store.register({key: value for key, value in store.fielddefs.items() if key not in older})
    return bag_store


def _read_raw(bag_dir: Path) -> tuple[dict, dict, dict]:
    """Return ``({topic: _TopicMessages}, {topic: message count}, {type: schema text})`` of the bag in ``bag_dir``."""
    _check_bag_dir(bag_dir)
    try:
        _, files = find_bag_files(bag_dir)
    except BagError as exc:
        raise BagContentError(f'cannot open bag {bag_dir}: {exc}') from None
    topics: dict = {}
    counts: dict = {}
    schema_of: dict = {}
    texts: dict = {}

    def take(channel, message):
        messages = topics.get(channel.topic)
        if messages is None:
            messages = topics[channel.topic] = _TopicMessages('')
            schema_of[channel.topic] = channel.schema_id
        messages.log_times.append(message.log_time)
        messages.payloads.append(message.data)

    for path in files:
        try:
            result = read_messages(path, on_message=take)
        except BagError as exc:      # not an MCAP file, or one that cannot be opened
            raise BagContentError(f'cannot open bag {bag_dir}: {exc}') from None
        if not result.complete:
            raise BagContentError(f'cannot open bag {bag_dir}: it does not read to its end{_diagnose_mcap(bag_dir)}')
        for schema in result.schemas.values():
            texts.setdefault(schema.name, schema.data.decode(errors='replace'))
        for topic, schema_id in schema_of.items():
            schema = result.schemas.get(schema_id)
            if not topics[topic].msgtype and schema is not None:
                topics[topic].msgtype = schema.name
        schema_of.clear()
        for channel in result.channels.values():    # topics recorded without a message count 0
            counts.setdefault(channel.topic, 0)
        for topic, n in result.counts.items():
            counts[topic] = counts.get(topic, 0) + n
    for messages in topics.values():
        messages.in_log_time_order()
    return topics, counts, texts


def _fill_reference(out: dict, bag: _Bag, cols: dict) -> None:
    """Write the virtual leader's ``(x0, y0, z0, psi0, psi0')`` of each step into ``out['reference']``."""
    rows = _stack(cols, _REFERENCE)
    ok = bag.keep(topics.REFERENCE.name, _finite(np.hstack([rows, _stack(cols, _REFERENCE_CHECKED)])),
                  np.ones(len(rows), bool))
    take = _last_per_step(cols['step'], ok)
    out['reference'][cols['step'][take]] = rows[take]


def _fill_rows(out: dict, bag: _Bag, spec, uh: int, c: int, last_step: int, parts: dict) -> None:
    """Write UH ``uh``'s messages of ``spec`` into column ``c`` of the arrays ``parts`` names.

    ``parts`` maps an output array to the fields it takes; a message counts when all of them are
    finite and it carries UH ``uh``'s id (else it is rejected), and only up to ``last_step``.
    """
    name = topics.uh_topic(uh, spec)
    fields = [f for group in parts.values() for f in group]
    cols = bag.columns(name, spec.type, fields)
    if cols is None:
        return
    in_run = cols['step'] <= last_step
    ok = bag.keep(name, _finite(_stack(cols, fields)) & (cols['uh_id'] == uh), in_run)
    take = _last_per_step(cols['step'], ok)
    for array, group in parts.items():
        out[array][cols['step'][take], c] = _stack(cols, group)[take]


def _fill_status(out: dict, bag: _Bag, uh: int, c: int, last_step: int) -> None:
    """Write UH ``uh``'s fault estimates, ``u_p``, saturation and safety filter activity into column ``c`` of ``out``.

    The fault isolation of its last status (the highest step; the later message of equal steps) goes to
    ``out['isolation'][uh]``; the mean and largest age of the neighbour states it used, s, go to
    ``out['neighbour_ages'][uh]`` (absent when it used none).
    """
    name = topics.uh_topic(uh, topics.STATUS)
    cols = bag.columns(name, topics.STATUS.type, _STATUS_P + _STATUS_W + _xyz('u_p') + SATURATION_FLAGS
                       + ('safety_active', 'neighbour_age_mean', 'neighbour_age_max'))
    if cols is None:
        return
    ok = (cols['step'] <= last_step) & (cols['uh_id'] == uh)
    if not ok.any():
        return
    take = _last_per_step(cols['step'], ok)
    steps = cols['step'][take]
    out['fault_est_p'][steps, c] = _stack(cols, _STATUS_P)[take]
    out['fault_est_w'][steps, c] = _stack(cols, _STATUS_W)[take]
    out['u_p'][steps, c] = _stack(cols, _xyz('u_p'))[take]
    out['saturated'][steps, c] = _stack(cols, SATURATION_FLAGS)[take].any(axis=1)
    out['safety_active'][steps, c] = cols['safety_active'][take] != 0
    means, maxes = cols['neighbour_age_mean'][take], cols['neighbour_age_max'][take]
    if np.isfinite(means).any():   # the ages of the neighbour states it used, s (docs/topics.md#neighbour-ages)
        out['neighbour_ages'][uh] = (float(np.nanmean(means)), float(np.nanmax(maxes)))
    index = np.flatnonzero(ok)
    last = index[len(index) - 1 - np.argmax(cols['step'][index][::-1])]
    out['isolation'][uh] = _isolation_of(bag.decode(name, int(last)))


def _fault_injections(bag: _Bag, ids) -> list:
    """Return one mapping per message on ``/uhN/fault``: ``uh``, the message's fields, ``received_s`` (log time, s).

    What the simulators did with them (applied or rejected) is decided by
    :func:`uh_team.fault_metrics.injected_faults`, with the simulators' own rule.
    """
    records = []
    for uh in ids:
        name = topics.uh_topic(uh, topics.FAULT)
        messages = bag.topics.get(name)
        if messages is None or messages.msgtype != topics.FAULT.type:
            continue
        for k, log_ns in enumerate(messages.log_times):
            msg = bag.decode(name, k)
            records.append({'uh': uh, 'uh_id': int(msg.uh_id), 'channel': int(msg.channel), 'rho': float(msg.rho),
                            'bias_constant': float(msg.bias_constant), 'bias_amplitude': float(msg.bias_amplitude),
                            'bias_frequency': float(msg.bias_frequency), 'onset_time': float(msg.onset_time),
                            'stuck_in_place': bool(getattr(msg, 'stuck_in_place', False)), 'received_s': log_ns * 1e-9})
    return records


def _losses(bag: _Bag, ids, last_step: int) -> dict:
    """Give what the states carried of the team's losses (docs/resilience.md).

    ``{'known': {(i, j): step}, 'declared': {j: step}, 'leaving': {i: (step, -1)}}``: UH ``i``'s
    controller knew ``j`` lost at ``step`` (the state it sent next was the first to carry it), the
    earliest step ``j`` was declared lost by anyone, and the UHs whose own states carried their own
    declaration (they left; channel unknown, -1). Empty dicts when no state carried a lost set.
    """
    known, declared, leaving = {}, {}, {}
    for i in ids:
        name = topics.uh_topic(i, topics.STATE)
        messages = bag.topics.get(name)
        if messages is None or messages.msgtype != topics.STATE.type:
            continue
        for k in range(len(messages.log_times)):
            msg = bag.decode(name, k)
            if int(msg.uh_id) != i or int(msg.step) > last_step:
                continue
            for j, step in zip(getattr(msg, 'lost_uhs', ()), getattr(msg, 'lost_steps', ()), strict=False):
                j, step = int(j), int(step)
                known[(i, j)] = min(known.get((i, j), int(msg.step) - 1), int(msg.step) - 1)
                declared[j] = min(declared.get(j, step), step)
                if j == i:      # its own declaration: it left (the channel is not on the wire)
                    leaving[i] = (step, -1)
    return {'known': known, 'declared': declared, 'leaving': leaving}


def read_team_bag(bag_dir, scenario) -> dict:
    """Read the per-step topics of a team bag into arrays.

    Returns a dict with ``time`` (K+1,), ``states`` (K+1, n, 12), ``commands`` (K+1, n, 4),
    ``reference`` (K+1, 5) = (x0, y0, z0, psi0, psi0'), ``fault_true_p``/``fault_true_w`` and
    ``fault_est_p``/``fault_est_w`` (K+1, n, 3), ``u_p`` (K+1, n, 3), ``saturated`` (K+1, n) (any
    saturation flag), ``isolation`` (the last fault isolation each controller published,
    :func:`_isolation_of`; ``{}`` when no status carried one), ``neighbour_ages`` (``{uh: (mean s, max s)}``
    of the neighbour states each controller used, from its status), ``counts`` ({topic: messages}),
    ``fault_injections`` (every message on ``/uhN/fault``, :func:`_fault_injections`) and, for a
    scenario with ``events`` or ``resilience``, ``losses`` (:func:`_losses`). Steps missing from a topic
    are NaN (the arrays of :func:`uh_team.run_arrays.new_run_arrays`). The numeric fields are read as
    columns (:mod:`uh_report.cdr_columns`).
    """
    bag_dir = Path(bag_dir)
    ids = list(scenario.ids)
    bag = _Bag(bag_dir)
    reference = bag.columns(topics.REFERENCE.name, topics.REFERENCE.type, _REFERENCE + _REFERENCE_CHECKED)
    if reference is None or not len(reference['step']):
        raise BagContentError(f'bag {bag_dir} has no {topics.REFERENCE.name} messages: not a team run')
    K = int(reference['step'].max())
    out = {'time': np.arange(K + 1) * scenario.dt, **new_run_arrays(K + 1, len(ids)), 'isolation': {},
           'neighbour_ages': {},
           'counts': bag.counts, 'rejected': bag.rejected, 'fault_injections': _fault_injections(bag, ids)}
    _fill_reference(out, bag, reference)
    for c, i in enumerate(ids):
        _fill_rows(out, bag, topics.STATE, i, c, K, {'states': _STATE})
        _fill_rows(out, bag, topics.COMMAND, i, c, K, {'commands': _COMMAND})
        _fill_rows(out, bag, topics.FAULT_TRUTH, i, c, K, {'fault_true_p': _FAULT_P, 'fault_true_w': _FAULT_W})
        _fill_status(out, bag, i, c, K)
    if scenario.events or scenario.resilience is not None:
        out['losses'] = _losses(bag, ids, K)
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
            f'`python -m uh_runtime.bags.bag recover {bag_dir}` restores it up to its last complete chunk')


def write_metrics_from_bag(bag_dir, scenario, case: str, out_path,
                           wall_time_s: float | None = None) -> tuple[dict, dict]:
    """Compute the metrics of docs/metrics.md from a team bag and write them to ``out_path`` (JSON).

    Returns ``(metrics, arrays)``: the metrics written and the arrays of :func:`read_team_bag`.
    """
    arrays = read_team_bag(bag_dir, scenario)
    metrics = metrics_from_arrays(arrays, scenario, case, wall_time_s=wall_time_s)
    Path(out_path).write_text(json.dumps(metrics, indent=2, sort_keys=False) + '\n')
    return metrics, arrays
