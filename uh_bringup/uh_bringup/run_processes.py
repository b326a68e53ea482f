"""The processes of a team run: which nodes share a process, and the command that starts each.

One process per node (``per-node``, each through its entry point), one per UH (``per-uh``: its sim
and controller; the team nodes and the recorder in one more each), a few workers (``workers``: the
UHs in ``workers`` blocks of consecutive ids, one process each; the team nodes and the recorder in
one more each) or everything in one (``single``); composed processes run
:mod:`uh_bringup.composed` on a node list in JSON.
"""
from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

from uh_bringup.team_nodes import NODES

__all__ = ['entry_command', 'process_commands', 'processes', 'group_kind', 'worker_groups', 'default_workers']


def entry_command(package: str, executable: str) -> list:
    """Return the command that starts a node's entry point.

    ``ros2 run`` on a ROS 2 machine (the backend is chosen by the node's ``UH_BACKEND``), else the
    venv script.
    """
    if shutil.which('ros2') and os.environ.get('ROS_DISTRO'):
        return ['ros2', 'run', package, executable]
    script = Path(sys.executable).with_name(executable)
    return [str(script)] if script.exists() else [executable]


def process_commands(specs, layout: str, spec_dir: Path, workers: int | None = None) -> list[tuple[str, list]]:
    """Return ``[(process name, command), ...]`` of the team's processes in layout ``layout``.

    One process per node (``per-node``, each through its entry point), one per UH (``per-uh``: its
    sim and controller; the team nodes and the recorder in one more each), ``workers`` processes
    holding blocks of UHs (``workers``: :func:`worker_groups`) or everything in one (``single``).
    The process holding the clock is last.
    """
    return [(name, cmd) for name, _kind, cmd in processes(specs, layout, spec_dir, workers)]


def default_workers() -> int:
    """Workers of the ``workers`` layout when not given: the CPUs this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def worker_groups(uh_ids, workers: int) -> dict[int, str]:
    """Return ``{uh id: process name}`` of the ``workers`` layout: consecutive ids, blocks as even as can be.

    ``workers`` is capped at the number of UHs; a block is named ``uhA-B`` by its first and last id
    (``uhA`` for one UH), so its kind is that of a UH's process (:func:`group_kind`).
    """
    ids = sorted(uh_ids)
    count = max(1, min(int(workers), len(ids)))
    out = {}
    for w in range(count):
        block = ids[w * len(ids) // count:(w + 1) * len(ids) // count]
        name = f'uh{block[0]}' if len(block) == 1 else f'uh{block[0]}-{block[-1]}'
        out.update({i: name for i in block})
    return out


def group_kind(group: str) -> str:
    """Return the node kind that decides what a composed process's death means (:mod:`uh_bringup.run_watch`)."""
    if group in ('recorder', 'live_view'):
        return group
    return 'sim' if group.startswith('uh') else 'clock'


def processes(specs, layout: str, spec_dir: Path, workers: int | None = None) -> list[tuple[str, str, list]]:
    """As :func:`process_commands`, with the node kind of each process (for composed ones, :func:`group_kind`)."""
    if layout == 'per-node':
        return [(name, kind, entry_command(NODES[kind].package, NODES[kind].executable) + args)
                for name, kind, args in specs]
    blocks = {}
    if layout == 'workers':
        uh_ids = {int(name.split('_')[0][2:]) for name, _kind, _args in specs if name.startswith('uh')}
        blocks = worker_groups(uh_ids, workers or default_workers()) if uh_ids else {}
    groups: dict[str, list] = {}
    for name, kind, args in specs:
        if layout == 'single':
            group = 'team'
        elif name.startswith('uh'):
            group = name.split('_')[0]
            group = blocks.get(int(group[2:]), group)
        else:
            group = kind if kind in ('recorder', 'live_view') else 'team'
        groups.setdefault(group, []).append({'node': kind, 'name': name, 'cli_args': args})
    spec_dir.mkdir(parents=True, exist_ok=True)
    out = []
    for group, nodes in sorted(groups.items(), key=lambda g: any(n['node'] == 'clock' for n in g[1])):
        path = spec_dir / f'{group}.nodes.json'
        path.write_text(json.dumps(nodes, indent=1))
        out.append((group, group_kind(group), [sys.executable, '-P', '-m', 'uh_bringup.composed', str(path)]))
    return out
