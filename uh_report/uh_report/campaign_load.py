"""The campaign a report is made of: its results file read back (:mod:`uh_team.campaign_store`).

:func:`load_campaign` reads ``campaign.sqlite`` into a :class:`Campaign` (the campaign's values,
its runs as ``{column: ndarray}``, its cases in :data:`CASE_ORDER`, its sweep);
:func:`is_campaign_dir` tells a campaign directory from a run directory.
"""
from __future__ import annotations

import json
import sqlite3
from dataclasses import dataclass, field
from pathlib import Path

from uh_team.campaign_store import DB_NAME, StoreError, open_store, read_meta, read_runs

__all__ = ['CampaignReportError', 'Campaign', 'is_campaign_dir', 'load_campaign', 'CASE_ORDER']

#: Canonical order of the controller cases (pairs are formed in this order: proposed vs case1,
#: proposed vs case2, case1 vs case2); other case names follow alphabetically.
CASE_ORDER = ('proposed', 'case1', 'case2')


class CampaignReportError(ValueError):
    """A campaign directory or results file that cannot be reported; the message says which and why."""


@dataclass
class Campaign:
    """One campaign as the report sees it.

    Attributes
    ----------
    directory : Path
        The campaign directory as given on the command line (re-run commands are relative to it).
    name : str
        The campaign's name (its directory name when the store has none).
    meta : dict
        Campaign-level values of the store, JSON decoded where they are JSON.
    runs : dict
        ``{column: ndarray}`` of :func:`uh_team.campaign_store.read_runs`.
    cases : list of str
        Controller cases, in :data:`CASE_ORDER`.
    planned_runs : int or None
        Runs of the complete campaign (draws x cases x sweep points), None if the store does not say.
    sweep_parameter : str or None
        The swept scenario parameter (e.g. ``impairments.delay_steps``), None without a sweep.
    sweep_values : list
        The swept values in sweep-index order (empty without a sweep).
    """

    directory: Path
    name: str
    meta: dict
    runs: dict
    cases: list
    planned_runs: int | None = None
    sweep_parameter: str | None = None
    sweep_values: list = field(default_factory=list)

    @property
    def done_runs(self) -> int:
        """Runs stored so far."""
        return len(self.runs['draw'])




def is_campaign_dir(path) -> bool:
    """Whether ``path`` is a campaign.

    A directory holding ``campaign.sqlite`` or a ``scenarios/`` folder (a campaign that has not stored a run yet;
    :func:`load_campaign` says so), or the ``.sqlite`` results file itself. Run directories (``bag/``, ``run.json``,
    ``timeseries.npz``) are not.
    """
    path = Path(path)
    if path.is_file():
        return path.suffix == '.sqlite'
    if not path.is_dir():
        return False
    if (path / DB_NAME).exists():
        return True
    is_run = any((path / marker).exists() for marker in ('bag', 'run.json', 'timeseries.npz', 'metadata.yaml'))
    return (path / 'scenarios').is_dir() and not is_run


def _decoded(value):
    """Return a stored meta value: its JSON content, or the string itself when it is not JSON."""
    if not isinstance(value, str):
        return value
    try:
        return json.loads(value)
    except ValueError:
        return value


def _case_rank(case: str):
    return (CASE_ORDER.index(case), '') if case in CASE_ORDER else (len(CASE_ORDER), case)


def load_campaign(path) -> Campaign:
    """Read the campaign in directory ``path`` (or the results file ``path``).

    Raises
    ------
    CampaignReportError
        No ``campaign.sqlite``, a file that is not a campaign results file (not SQLite, damaged, or
        of another layout), or a campaign with no stored run yet.
    """
    path = Path(path)
    directory, db = (path.parent, path) if path.is_file() else (path, path / DB_NAME)
    if not db.is_file():
        raise CampaignReportError(f'{directory}: no {DB_NAME}: the campaign has not stored a run yet '
                                  '(or this is not a campaign directory)')
    try:
        con = open_store(db)
    except StoreError as exc:
        raise CampaignReportError(str(exc)) from None
    try:
        meta = {key: _decoded(value) for key, value in read_meta(con).items()}
        runs = read_runs(con)
    except sqlite3.DatabaseError as exc:
        raise CampaignReportError(f'{db}: cannot be read, damaged? ({exc})') from None
    finally:
        con.close()

    name = str(meta.get('name') or directory.resolve().name)
    sweep_parameter = meta.get('sweep_parameter') or None
    sweep_values = list(meta.get('sweep_values') or []) if sweep_parameter else []
    meta_cases = [str(c) for c in meta.get('cases') or []]
    cases = sorted(set(meta_cases) | {str(c) for c in runs['case_name']}, key=_case_rank)
    draws = meta.get('runs')
    planned = None
    if isinstance(draws, int) and meta_cases:
        planned = draws * len(meta_cases) * max(1, len(sweep_values))
    if len(runs['draw']) == 0:
        of = f' of {planned} planned' if planned else ''
        raise CampaignReportError(f'{db}: campaign {name!r} has no runs stored yet (0{of}); report it once '
                                  'some runs have finished')
    return Campaign(directory=directory, name=name, meta=meta, runs=runs, cases=cases, planned_runs=planned,
                    sweep_parameter=str(sweep_parameter) if sweep_parameter else None, sweep_values=sweep_values)

