"""Starting ``scripts/run_formation.sh`` from tests, waiting for its logs and leaving nothing behind."""
import os
import signal
import subprocess
import time
from pathlib import Path

RUN = Path(__file__).resolve().parents[1] / 'scripts' / 'run_formation.sh'


def start_run(out, domain, *extra):
    """Start the run supervisor writing to ``out`` on DDS domain ``domain``, in its own session.

    The session lets a test kill the whole tree; stdout and stderr come together as text.
    """
    return subprocess.Popen([str(RUN), '--out', str(out), '--domain-id', str(domain), *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)


def wait_for_log(path: Path, needle: str, proc, timeout: float) -> None:
    """Wait until ``needle`` appears in the log ``path``; fail if ``proc`` ends first or on timeout."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if path.exists() and needle in path.read_text(errors='replace'):
            return
        if proc.poll() is not None:
            raise AssertionError(f'run ended before {needle!r} appeared in {path}:\n{proc.stdout.read()}')
        time.sleep(0.05)
    raise AssertionError(f'{needle!r} did not appear in {path} within {timeout} s')


def stop_run(proc, timeout: float = 60.0) -> None:
    """End a run supervisor started in its own session the way Ctrl-C does (SIGINT), then kill what is left.

    SIGINT makes the supervisor stop every node it started. Killing only the supervisor would orphan its nodes, which
    live on in the test's DDS domain and meet the next test that takes that id.
    """
    if proc.poll() is not None:
        return
    try:
        os.killpg(proc.pid, signal.SIGINT)
        proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    except ProcessLookupError:
        pass


def kill_session(proc) -> None:
    """Kill the whole session of ``proc`` (started with ``start_new_session``) if it still runs, and reap it.

    The clean-up of a test that started a run or a campaign, whatever its outcome: nothing it
    started may live on in the test's DDS domain or hold its CPU.
    """
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def assert_lockstep_run_equals_in_process(tmp_path, scenario, scenario_text: str, duration: float = 3.0):
    """Run ``scenario_text`` in lockstep (one process per node, no visualisation); return ``(run dir, in-process run)``.

    Asserts the run ends with status 0 and that its bag's states and commands equal the in-process run of
    ``scenario`` (the same scenario, parsed) to the bit.
    """
    import numpy as np

    from uh_report.bag_metrics import read_team_bag
    from uh_runtime.network import reserve_domain_id
    from uh_team.team_simulation import run_team_simulation
    scenario_file = tmp_path / 'scenario.yaml'
    scenario_file.write_text(scenario_text)
    out = tmp_path / 'run'
    proc = start_run(out, reserve_domain_id(), '--clock', 'lockstep', '--scenario', str(scenario_file),
                     '--duration', f'{duration:g}', '--no-visualization')
    output, _ = proc.communicate(timeout=300)
    assert proc.returncode == 0, output
    reference = run_team_simulation(scenario, 'proposed', duration=duration)
    bag = read_team_bag(out / 'bag', scenario)
    for name, expected in (('states', reference.states), ('commands', reference.commands)):
        assert np.array_equal(bag[name], expected), first_difference(name, bag[name], expected, scenario.ids)
    return out, reference


def first_difference(name: str, got, expected, ids) -> str:
    """Describe where two (steps, UHs, values) arrays first differ: step, UH, both rows, missing or not."""
    import numpy as np
    if got.shape != expected.shape:
        return f'{name}: shape {got.shape} != {expected.shape}'
    differs = ~((got == expected) | (np.isnan(got) & np.isnan(expected)))
    steps, cols = np.nonzero(differs.any(axis=2))
    k, c = int(steps[0]), int(cols[0])
    missing = 'missing from the bag' if np.isnan(got[k, c]).all() else 'a different value'
    return (f'{name} differ at {len(steps)} (step, UH) pairs; first step {k}, UH {ids[c]}: {missing}; '
            f'bag {got[k, c].tolist()} expected {expected[k, c].tolist()}')


def controller_reads(domain: int, uh_ids, timeout: float = 30.0) -> dict:
    """Return the topics each ``/uhN/controller`` of ``uh_ids`` reads, from the live graph of DDS domain ``domain``.

    Read from DDS discovery and ``ros_discovery_info`` while the run goes on: ``{N: {topic, ...}}``.
    """
    from uh_runtime.dds.graph import Graph
    from uh_runtime.network import loopback_config
    os.environ.setdefault('CYCLONEDDS_URI', loopback_config())  # the run's network configuration
    graph = Graph(domain_id=domain)
    try:
        def complete(_graph):
            names = {(n, ns) for n, ns in graph.node_names_and_namespaces()}
            return all(('controller', f'/uh{i}') in names for i in uh_ids)
        assert graph.wait_until(complete, timeout_sec=timeout), 'controllers not discovered'
        graph.settle(1.0)
        reads = {}
        for topic, _types in graph.topic_names_and_types():
            for ep in graph.endpoints(topic, writers=False):
                if ep.node_name == 'controller':
                    reads.setdefault(int(ep.node_namespace[3:]), set()).add(topic)
        return reads
    finally:
        graph.close()
