"""A run's node table: the nodes of a team run that a listing from another terminal waits for.

A run's ``env.sh`` exports it as ``UH_RUN_NODES`` (the nodes' fully qualified names, comma-separated).
The ``uh`` commands that read the graph wait up to ``--spin-time`` for every one of those nodes, answer
as soon as all are seen, and name the ones not seen (docs/topics.md#inspecting-a-running-team). Light:
no DDS import, so ``uh --help`` stays fast.
"""
import os
import shlex
import sys

from ..dds.arguments import InvalidNameError, validate_namespace, validate_node_name

__all__ = ['RUN_NODES_VARIABLE', 'export_line', 'run_nodes', 'report_missing']

#: Environment variable of a run's node table.
RUN_NODES_VARIABLE = 'UH_RUN_NODES'


def export_line(nodes) -> str:
    """Return the lines of ``env.sh`` that export the node table ``nodes`` (fully qualified names)."""
    return (f"# the run's nodes: uh node list, uh topic list wait for them and name any not seen\n"
            f'export {RUN_NODES_VARIABLE}={shlex.quote(",".join(nodes))}\n')


def run_nodes(domain_id, env=None) -> list:
    """Return the sorted node table of ``env`` (default ``os.environ``) for a command on ``domain_id``.

    Empty when ``UH_RUN_NODES`` is unset or empty, or when ``domain_id`` (None: the environment's) is
    not the environment's ``ROS_DOMAIN_ID``: the table is that domain's. ValueError for an invalid name.
    """
    env = os.environ if env is None else env
    text = env.get(RUN_NODES_VARIABLE, '').strip()
    if not text or (domain_id is not None and str(domain_id) != env.get('ROS_DOMAIN_ID', '').strip()):
        return []
    names = set()
    for name in (part.strip() for part in text.split(',')):
        if not name:
            continue
        namespace, _, base = name.rpartition('/')
        try:
            if not name.startswith('/'):
                raise InvalidNameError('a fully qualified node name starts with /')
            validate_namespace(namespace or '/')
            validate_node_name(base)
        except InvalidNameError as exc:
            raise ValueError(f'{RUN_NODES_VARIABLE}: node {name!r}: {exc}') from None
        names.add(name)
    return sorted(names)


def report_missing(missing, table: int, spin_time: float) -> int:
    """Return a listing's exit status: 0, or 1 after naming on stderr the ``missing`` of the ``table`` nodes."""
    if not missing:
        return 0
    sys.stdout.flush()
    print(f"uh: warning: {len(missing)} of the run's {table} nodes ({RUN_NODES_VARIABLE}, from its env.sh) not "
          f'seen within {spin_time:g} s, so left out of this answer: {", ".join(missing)} (has the run ended? '
          'else try a longer --spin-time)', file=sys.stderr)
    return 1
