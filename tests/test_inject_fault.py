"""``scripts/inject_fault.sh`` against a simulator's fault subscription: delivery, and leaving the graph.

The injector shuts its context down without announcing its node's removal in ``ros_discovery_info``
first (which made the participant's deletion wait for every reader in a team to acknowledge it):
the peers must still see the node leave with the participant, not only when its lease expires.
"""
import json
import subprocess
import sys
from pathlib import Path

import pytest

from uh_runtime.dds.graph import Graph

pytestmark = pytest.mark.dds

ROOT = Path(__file__).resolve().parents[1]
HELPERS = Path(__file__).resolve().parent / 'helpers_runtime'
TIMEOUT = 30.0   # s; bounds a failure only
#: s: well below Cyclone DDS's participant lease (10 s), after which a vanished peer is dropped anyway
LEAVES_WITHIN = 5.0


def _inject_fault_node(graph):
    return ('inject_fault', '/') in graph.node_names_and_namespaces()


def test_the_fault_reaches_the_simulator_and_the_injector_leaves_the_graph_at_exit(domain_id, processes, tmp_path):
    with Graph(domain_id=domain_id) as graph:
        # started before the simulator, it waits for it (--timeout): long enough to be seen in the graph
        inject = processes.start([str(ROOT / 'scripts' / 'inject_fault.sh'), '--domain-id', str(domain_id),
                                  '--uh', '2', '--channel', 'lateral', '--rho', '0.6', '--onset', '12.5',
                                  '--timeout', str(TIMEOUT)],
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
        assert graph.wait_until(_inject_fault_node, TIMEOUT), inject.stderr.read() if inject.poll() else ''
        sim = processes.start([sys.executable, str(HELPERS / 'fault_listener.py'), '--ros-args', '-r', '__ns:=/uh2'],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
        _, err = inject.communicate(timeout=TIMEOUT)
        assert inject.returncode == 0, err
        assert 'injected on /uh2/fault: lateral rho 0.6' in err and 'warning' not in err, err
        assert json.loads(sim.stdout.readline()) == {'uh_id': 2, 'channel': 2, 'rho': 0.6, 'onset_time': 12.5}
        assert graph.wait_until(lambda g: not _inject_fault_node(g), LEAVES_WITHIN), \
            f'inject_fault still in the graph {LEAVES_WITHIN} s after it exited'
