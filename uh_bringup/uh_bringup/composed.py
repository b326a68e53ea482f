"""Several nodes in one process, spun by one executor (ROS 2 composition, manual style).

``python -m uh_bringup.composed SPEC.json`` builds every node listed in the JSON file (node kinds of
:data:`uh_bringup.team_nodes.NODES`)::

    [{"node": "sim", "cli_args": ["--ros-args", "-r", "__ns:=/uh1", "-p", "uh_id:=1", ...]}, ...]

with its own command-line arguments (namespace, parameters) exactly as its entry point would get
them, adds them all to one single-threaded executor and spins until the process is interrupted
or, when the clock is one of them, until the run is complete. Behaviour is the same as one process
per node: the lockstep data flow does not depend on which process a node lives in.
"""
from __future__ import annotations

import json
import sys

import uh_runtime as rt
from uh_bringup.team_nodes import node_class
from uh_core import compiled_kernels

__all__ = ['main']


def main(argv=None) -> int:
    """Build the nodes of the JSON node list ``argv[0]`` and spin them in one executor; return the exit status.

    The spinning ends at shutdown or once a node (the clock) is ``done``; the status is 1 when a node
    reports ``failed``, 2 for a bad command line or an unreadable node list (``-h`` prints the usage, 0).
    """
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1 or argv[0] in ('-h', '--help'):
        print(__doc__, file=sys.stderr)
        return 0 if argv and argv[0] in ('-h', '--help') else 2
    try:
        with open(argv[0]) as f:
            specs = json.load(f)
    except (OSError, json.JSONDecodeError) as exc:
        print(f'composed: error: cannot read node list {argv[0]}: {exc}', file=sys.stderr)
        return 2
    compiled_kernels.prefer_compiled()   # as the node entry points: the nodes' kernels without numba where built
    nodes = []

    def build():
        for spec in specs:
            nodes.append(node_class(spec['node'])(cli_args=list(spec.get('cli_args', []))))
        return nodes

    def finished(_first):
        return any(getattr(node, 'done', False) for node in nodes)

    def exit_code(_first):
        return 1 if any(getattr(node, 'failed', None) for node in nodes) else 0

    return rt.run_node(build, [sys.argv[0]], until=finished, exit_code=exit_code)


if __name__ == '__main__':
    sys.exit(main())
