"""Setting a team run up: its DDS domain and environment, real-time scheduling, the network, the processes.

Every run has a DDS domain of its own (``--domain-id``, else ``ROS_DOMAIN_ID``, else a free one
held for the run), so runs started at once never see each other; ``env.sh`` in the output
directory gives another terminal the same settings, and the run's node table, for which ``uh node
list`` and ``uh topic list`` wait (docs/topics.md#inspecting-a-running-team).
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

from uh_bringup import netns
from uh_bringup.run_checks import UsageError
from uh_bringup.run_processes import processes
from uh_bringup.run_secure import inspect_script
from uh_bringup.team_nodes import backend_environment, node_specs
from uh_runtime import scheduling
from uh_runtime.bags import live_view
from uh_runtime.cli.node_table import export_line
from uh_runtime.network import environment_script, loopback_environment, reserve_domain_id

__all__ = ['run_environment', 'realtime_priority', 'write_environment_script', 'open_network', 'start_team',
           'dds_processes', 'team_specs', 'run_node_names']


def run_environment(domain_id, domains: tuple | None = None) -> tuple[int, dict]:
    """Return ``(domain, environment of the run's processes)``; the domain is reserved if not given.

    ``domains``: ``(first, last)`` to reserve from (a secure run's keystore allows 0..230 at most).
    """
    domain = domain_id
    if domain is None:
        # held by this process for the run, so that runs started at once never share a domain
        domain = int(os.environ['ROS_DOMAIN_ID']) if os.environ.get('ROS_DOMAIN_ID', '').isdigit() \
            else reserve_domain_id(*(domains or ()))
    try:
        env = loopback_environment(domain)
    except ValueError as exc:   # a bad ROS_AUTOMATIC_DISCOVERY_RANGE
        raise UsageError(str(exc)) from None
    env['PYTHONUNBUFFERED'] = '1'
    return domain, env


def realtime_priority(args) -> int:
    """Return the SCHED_FIFO priority the control loop's nodes get (0: normal scheduling); say which."""
    priority = args.realtime_priority if args.clock == 'realtime' else 0
    if priority:
        why_not = scheduling.permitted(priority)
        print(f'[run] real-time scheduling: SCHED_FIFO priority {priority} for the clock, simulators, controllers '
              'and virtual leader' if why_not is None else
              f'[run] real-time scheduling not available, the control loop runs at normal priority and may miss '
              f'steps on a busy machine: {why_not}', file=sys.stderr)
        priority = priority if why_not is None else 0
    return priority


def run_node_names(specs) -> list[str]:
    """Return the fully qualified names of the nodes of ``specs`` (:func:`team_specs`), sorted.

    Each node is named after its kind (``sim``, ``clock``, ...: every node class gives its kind as its
    name) in the namespace of its ``__ns:=`` remapping, the root without one.
    """
    names = set()
    for _name, kind, ros_args in specs:
        namespace = next((a.split(':=', 1)[1] for a in ros_args if a.startswith('__ns:=')), '/')
        names.add(f"{namespace.rstrip('/')}/{kind}")
    return sorted(names)


def write_environment_script(out: Path, env: dict, nodes=()) -> None:
    """Write ``out/env.sh`` and say how another terminal uses it.

    ``nodes``, the run's fully qualified node names (:func:`run_node_names`), go in as ``UH_RUN_NODES``:
    ``uh node list`` and the other listings of ``uh`` wait for them and name those they do not see. A secure
    run's also gives the read-only identity (:func:`uh_bringup.run_secure.inspect_script`).
    """
    print(f'[run] output: {out}', file=sys.stderr)
    secure = inspect_script(env) if env.get('ROS_SECURITY_ENABLE') == 'true' else ''
    (out / 'env.sh').write_text(environment_script(env) + (export_line(nodes) if nodes else '') + secure)
    print(f'[run] from another terminal: source {out / "env.sh"}   (then ros2 topic list, or uh topic list)',
          file=sys.stderr)


def open_network(args, scenario):
    """With ``--hosts netns``: the team's network namespaces (:class:`uh_bringup.netns.TeamNetwork`), else None."""
    if args.hosts != 'netns':
        return None
    swept = netns.sweep_stale()
    if swept:
        print(f'[run] removed {len(swept)} network namespaces left by runs that were killed', file=sys.stderr)
    network = netns.TeamNetwork(scenario.ids, args.loss).__enter__()
    print(f'[run] network: {network.describe()}', file=sys.stderr)
    return network


def dds_processes(env: dict, names: list) -> set:
    """Return the process names ``UH_DDS_PROCESSES`` (comma-separated) puts on the Cyclone DDS backend.

    A mixed team: those processes run on the Cyclone DDS backend, the others on rclpy where it is
    importable (docs/ros2.md#rclpy-from-pypi-wheels). A name the run does not have is a usage error.
    """
    wanted = {n.strip() for n in env.get('UH_DDS_PROCESSES', '').split(',') if n.strip()}
    unknown = sorted(wanted - set(names))
    if unknown:
        raise UsageError(f'UH_DDS_PROCESSES names {", ".join(unknown)}, which this run does not start; '
                         f'its processes: {", ".join(names)}')
    return wanted


def team_specs(args, scenario, scenario_arg: str, out: Path, priority: int) -> list:
    """Return the :func:`~uh_bringup.team_nodes.node_specs` of the run of ``args`` (recorder first, clock last)."""
    return node_specs(scenario, scenario_arg, args.case, args.clock, args.rate, args.duration,
                      out / 'bag', args.startup_timeout, args.stale_timeout,
                      visualization=not args.no_visualization,
                      standard_views=not args.no_standard_views,
                      live_view=(args.foxglove_host, args.foxglove) if args.foxglove is not None else None,
                      realtime_priority=priority)


def start_team(args, specs, out: Path, env: dict, sup, network) -> None:
    """Start the processes of the team's nodes ``specs`` (:func:`team_specs`) under ``sup``, the clock's last."""
    if args.foxglove is not None:
        print(f'[run] live view: {live_view.connect_hint(args.foxglove_host, args.foxglove)}', file=sys.stderr)
    started = processes(specs, args.processes, out / 'logs', getattr(args, 'workers', None))
    on_dds = dds_processes(env, [name for name, _kind, _cmd in started])
    # a secure run (one process per node): each node's identity is its fully qualified name
    enclaves = {spec[0]: run_node_names([spec])[0] for spec in specs} if env.get('ROS_SECURITY_ENABLE') else {}
    for name, kind, cmd in started:
        # composed processes: only the recorder's own process (per-uh) is of an infrastructure kind
        node_env = {**env, **backend_environment(kind, env), **({'UH_BACKEND': 'dds'} if name in on_dds else {})}
        if name in enclaves:
            node_env['ROS_SECURITY_ENCLAVE_OVERRIDE'] = enclaves[name]
        if network is not None:
            sup.prefix[name] = network.prefix(name)
            node_env = network.environment(name, node_env)
        if node_env != env:
            sup.envs[name] = node_env
        sup.start(name, cmd, kind=kind)
