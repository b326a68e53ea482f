"""The results of a campaign: one SQLite file, ``DIR/campaign.sqlite`` (docs/campaigns.md#results).

One row per *run*: a (draw, sweep point, case) triple. A run is committed on its own as soon as it
ends, so an interrupted campaign loses at most the runs in flight, and a resumed one skips every
key already in the table. Tables:

``campaign(key TEXT PRIMARY KEY, value TEXT)``
    ``spec`` (the spec's text), ``spec_digest`` (sha256 of the text), ``spec_path``, ``created``,
    ``versions`` (JSON of the packages that produced the numbers).
``runs``
    The columns of :data:`RUN_COLUMNS` with primary key ``(draw, sweep_index, case_name)``.

Readers use :func:`read_runs` (a dict of numpy arrays, one per column, in key order), never SQL of
their own, so the layout has one definition.
"""
from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import numpy as np

from .metric_registry import stored_metrics

__all__ = ['RUN_COLUMNS', 'METRIC_COLUMNS', 'STATUSES', 'DB_NAME', 'StoreError', 'open_store',
           'write_meta', 'read_meta', 'done_keys', 'write_run', 'read_runs', 'metric_row']

#: File name of the results file inside the campaign directory.
DB_NAME = 'campaign.sqlite'

#: Outcome of a run: ``ok`` (ran to the end), ``diverged`` (a state became non-finite; the reason
#: names step and UH), ``failed`` (anything else raised; the reason is the exception).
STATUSES = ('ok', 'diverged', 'failed')

#: Metric columns (REAL, NULL when undefined or the run did not end): name -> meaning, those of
#: :func:`uh_team.metric_registry.stored_metrics`. The values come from
#: :func:`uh_team.metrics.metrics_from_arrays` through :func:`metric_row`.
METRIC_COLUMNS = {metric.name: metric.description for metric in stored_metrics()}

#: Every column of ``runs`` in order: (name, SQL type).
RUN_COLUMNS = (
    ('draw', 'INTEGER NOT NULL'),          # index of the random draw, 0..runs-1
    ('sweep_index', 'INTEGER NOT NULL'),   # index into the sweep's values (0 without a sweep)
    ('case_name', 'TEXT NOT NULL'),        # proposed, case1, case2
    ('sweep_value', 'REAL'),               # the swept parameter's value (NULL without a sweep)
    ('status', 'TEXT NOT NULL'),           # one of STATUSES
    ('reason', 'TEXT'),                    # why a run did not end ok
    ('success', 'INTEGER'),                # 1 when ok and within the spec's success thresholds
    ('scenario_file', 'TEXT'),             # the resolved scenario, relative to the campaign dir
    ('wall_time_s', 'REAL'),               # wall time of the run (simulation and metrics), s
    *((name, 'REAL') for name in METRIC_COLUMNS),
)
_KEY = ('draw', 'sweep_index', 'case_name')


class StoreError(RuntimeError):
    """A results file that cannot be opened, or belongs to another spec."""


def open_store(path) -> sqlite3.Connection:
    """Open (creating if needed) the results file ``path``; tables are created if missing."""
    path = Path(path)
    try:
        con = sqlite3.connect(str(path), timeout=30.0)
        columns = ', '.join(f'{name} {kind}' for name, kind in RUN_COLUMNS)
        with con:
            con.execute('CREATE TABLE IF NOT EXISTS campaign (key TEXT PRIMARY KEY, value TEXT)')
            con.execute(f'CREATE TABLE IF NOT EXISTS runs ({columns}, PRIMARY KEY ({", ".join(_KEY)}))')
        have = [row[1] for row in con.execute('PRAGMA table_info(runs)')]
    except sqlite3.DatabaseError as exc:
        raise StoreError(f'{path}: not a campaign results file ({exc})') from None
    if have != [name for name, _ in RUN_COLUMNS]:
        con.close()
        raise StoreError(f'{path}: its runs table has other columns ({", ".join(have)}); it was written '
                         'by another version: start the campaign in a new directory')
    return con


def write_meta(con: sqlite3.Connection, **values) -> None:
    """Store campaign-level values (strings, or anything JSON can hold)."""
    with con:
        con.executemany('INSERT OR REPLACE INTO campaign (key, value) VALUES (?, ?)',
                        [(k, v if isinstance(v, str) else json.dumps(v)) for k, v in values.items()])


def read_meta(con: sqlite3.Connection) -> dict:
    """Campaign-level values as stored (strings)."""
    return dict(con.execute('SELECT key, value FROM campaign'))


def done_keys(con: sqlite3.Connection) -> set:
    """``{(draw, sweep_index, case_name)}`` of every run already stored (whatever its status)."""
    return set(con.execute(f'SELECT {", ".join(_KEY)} FROM runs'))


def write_run(con: sqlite3.Connection, row: dict) -> None:
    """Store one run and commit, so it survives an interruption right after.

    ``row`` is a dict with the columns of :data:`RUN_COLUMNS`; missing ones are NULL.
    """
    names = [name for name, _ in RUN_COLUMNS]
    unknown = set(row) - set(names)
    if unknown:
        raise ValueError(f'unknown result columns {sorted(unknown)}')
    if row.get('status') not in STATUSES:
        raise ValueError(f'status {row.get("status")!r}; allowed: {", ".join(STATUSES)}')
    with con:
        con.execute(f'INSERT OR REPLACE INTO runs ({", ".join(names)}) VALUES ({", ".join("?" * len(names))})',
                    [_sql(row.get(name)) for name in names])


def _sql(value):
    if isinstance(value, (np.integer, np.bool_, bool)):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    return value


def read_runs(path_or_con) -> dict:
    """Every stored run as ``{column: ndarray}`` in key order (draw, sweep_index, case_name).

    REAL columns are float arrays with NaN for NULL; INTEGER columns int arrays (``success`` -1
    for NULL); TEXT columns object arrays (None for NULL).
    """
    con = path_or_con if isinstance(path_or_con, sqlite3.Connection) else open_store(path_or_con)
    names = [name for name, _ in RUN_COLUMNS]
    rows = con.execute(f'SELECT {", ".join(names)} FROM runs ORDER BY {", ".join(_KEY)}').fetchall()
    out = {}
    for c, (name, kind) in enumerate(RUN_COLUMNS):
        values = [r[c] for r in rows]
        if kind.startswith('REAL'):
            out[name] = np.array([np.nan if v is None else v for v in values], dtype=float)
        elif kind.startswith('INTEGER'):
            out[name] = np.array([-1 if v is None else v for v in values], dtype=np.int64)
        else:
            out[name] = np.array(values, dtype=object)
    return out


def metric_row(metrics: dict) -> dict:
    """Return the :data:`METRIC_COLUMNS` of one run from its ``metrics_from_arrays`` result."""
    return {metric.name: metric.value(metrics) for metric in stored_metrics()}
