"""The processes of a team run: which nodes share a process, and the command that starts each.

One process per node (``per-node``, each through its entry point), one per UH (``per-uh``: its sim
and controller; the team nodes and the recorder in one more each) or everything in one
(``single``); composed processes run :mod:`uh_bringup.composed` on a node list in JSON.
"""
from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

from uh_bringup.team_nodes import NODES

__all__ = ['entry_command', 'process_commands', 'processes', 'group_kind']


def entry_command(package: str, executable: str) -> list:
    """Return the command that starts a node's entry point.

    ``ros2 run`` on a ROS 2 machine (the backend is chosen by the node's ``UH_BACKEND``), else the
    venv script.
    """
    if shutil.which('ros2') and os.environ.get('ROS_DISTRO'):
        return ['ros2', 'run', package, executable]
    script = Path(sys.executable).with_name(executable)
    return [str(script)] if script.exists() else [executable]


def process_commands(specs, layout: str, spec_dir: Path) -> list[tuple[str, list]]:
    """Return ``[(process name, command), ...]`` of the team's processes in layout ``layout``.

    One process per node (``per-node``, each through its entry point), one per UH (``per-uh``: its
    sim and controller; the team nodes and the recorder in one more each) or everything in one
    (``single``). The process holding the clock is last.
    """
    return [(name, cmd) for name, _kind, cmd in processes(specs, layout, spec_dir)]


def group_kind(group: str) -> str:
    """Return the node kind that decides what a composed process's death means (:mod:`uh_bringup.run_watch`)."""
    if group in ('recorder', 'live_view'):
        return group
    return 'sim' if group.startswith('uh') else 'clock'


def processes(specs, layout: str, spec_dir: Path) -> list[tuple[str, str, list]]:
    """As :func:`process_commands`, with the node kind of each process (for composed ones, :func:`group_kind`)."""
    if layout == 'per-node':
        return [(name, kind, entry_command(NODES[kind].package, NODES[kind].executable) + args)
                for name, kind, args in specs]
    groups: dict[str, list] = {}
    for name, kind, args in specs:
        if layout == 'single':
            group = 'team'
        elif name.startswith('uh'):
            group = name.split('_')[0]
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
