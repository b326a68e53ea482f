"""Every run records /markers (visualization_msgs/MarkerArray in frame world).

What the markers show agrees with the recorded states and reference: a run's bag opened in Foxglove Studio or replayed
to RViz2 shows the formation as it flew. Uses the shared 22 s lockstep run of tests/test_report.py; the bag is read with
rosbags (an independent reader).
"""
import numpy as np
import pytest
import yaml
from rosbags.rosbag2 import Reader
from test_report import shared_team_run

pytestmark = [pytest.mark.dds, pytest.mark.slow]

# docs/scenario.md: followers 4, 5 aim at w = -L1^-1 L2 = [[0.4, 0.4, 0.2], [0.2, 0.2, 0.6]] of the
# leaders 1, 2, 3 (written out here, independently of the scenario code)
CONTAINMENT_WEIGHTS = {4: (0.4, 0.4, 0.2), 5: (0.2, 0.2, 0.6)}
NAMESPACES = {'uh', 'label', 'trail', 'formation', 'hull', 'target', 'virtual_leader'}


@pytest.fixture(scope='module')
def recorded(tmp_path_factory):
    from uh_report.bag_metrics import read_team_bag
    from uh_runtime.messages import typestore
    from uh_topology.scenario import load_scenario
    run = shared_team_run(tmp_path_factory)
    store = typestore()
    with Reader(run / 'bag') as reader:
        conns = [c for c in reader.connections if c.topic == '/markers']
        arrays = [store.deserialize_cdr(raw, c.msgtype) for c, _, raw in reader.messages(connections=conns)]
    return run, conns, arrays, read_team_bag(run / 'bag', load_scenario('paper'))


def test_markers_are_recorded_over_the_whole_run_with_their_qos(recorded):
    run, conns, arrays, team = recorded
    assert [c.msgtype for c in conns] == ['visualization_msgs/msg/MarkerArray']
    meta = yaml.safe_load((run / 'bag' / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    entry = next(e for e in meta['topics_with_message_count'] if e['topic_metadata']['name'] == '/markers')
    qos = entry['topic_metadata']['offered_qos_profiles']
    qos = (yaml.safe_load(qos) if isinstance(qos, str) else qos)[0]   # rosbag2 writes it either way
    assert (qos['reliability'], qos['durability']) == ('reliable', 'transient_local')   # docs/topics.md
    stamps = [a.markers[0].header.stamp.sec + a.markers[0].header.stamp.nanosec * 1e-9 for a in arrays]
    assert stamps == sorted(stamps) and stamps[0] == 0.0
    assert stamps[-1] == pytest.approx(team['time'][-1])       # up to the last step of the run
    assert len(arrays) >= 10


def test_markers_show_the_recorded_formation(recorded):
    _, _, arrays, team = recorded
    dt = team['time'][1] - team['time'][0]
    for array in arrays[:: max(1, len(arrays) // 20)]:          # 20 snapshots over the run
        assert {mk.header.frame_id for mk in array.markers} == {'world'}
        assert {mk.ns for mk in array.markers} == NAMESPACES
        stamp = array.markers[0].header.stamp
        k = int(round((stamp.sec + stamp.nanosec * 1e-9) / dt))
        by = {(mk.ns, mk.id): mk for mk in array.markers}
        pos = lambda p: np.array([p.x, p.y, p.z])             # noqa: E731
        states = team['states'][k]
        for c, i in enumerate((1, 2, 3, 4, 5)):
            # each helicopter's arrow sits at the recorded position of that step
            assert np.array_equal(pos(by[('uh', i)].pose.position), states[c, 0:3])
        leaders = states[0:3, 0:3]
        for i, w in CONTAINMENT_WEIGHTS.items():
            assert np.allclose(pos(by[('target', i)].pose.position), np.asarray(w) @ leaders, rtol=0, atol=1e-12)
        assert np.array_equal(pos(by[('virtual_leader', 0)].pose.position), team['reference'][k, 0:3])
        hull = {tuple(pos(p)) for p in by[('hull', 0)].points}
        assert hull == {tuple(p) for p in leaders}                 # the leaders' triangle
