"""Ready-made views of a team: a Foxglove layout and an RViz2 configuration.

The views (docs/visualization.md#ready-made-views) are generated from a scenario so that they name
its UHs' topics and frames.

    python -m uh_bringup.views --scenario paper --out views     # writes formation.foxglove.json, formation.rviz

The Foxglove layout is built with foxglove-sdk's own layout types (``foxglove.layouts``). Both
views show the 3-D scene in ``world`` following the virtual leader (``/tf``, ``/markers``: formation
polygon, hull, trails), per-UH consensus errors and fault estimates against the truth, and
``/diagnostics``.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import yaml

from uh_core import frames
from uh_topology.scenario import load_scenario
from uh_wire import topics

__all__ = ['foxglove_layout', 'rviz_config', 'main', 'FOXGLOVE_FILE', 'RVIZ_FILE']

FOXGLOVE_FILE = 'formation.foxglove.json'
RVIZ_FILE = 'formation.rviz'


def _status(uh: int, field: str) -> str:
    return f'{topics.uh_topic(uh, topics.STATUS)}.{field}'


def foxglove_layout(scenario) -> str:
    """Return the layout as Foxglove's JSON: 3-D scene | consensus errors, fault estimate vs truth, diagnostics."""
    import foxglove.layouts as fl
    faulted = [i for i in scenario.ids if scenario.faults.get(i)] or list(scenario.ids)
    errors = fl.PlotPanel(title='consensus error z1 (x, y) per UH (m)', config=fl.PlotConfig(
        paths=[fl.PlotSeries(value=_status(i, 'z1.x'), label=f'uh{i} z1.x') for i in scenario.ids]
        + [fl.PlotSeries(value=_status(i, 'z1.y'), label=f'uh{i} z1.y') for i in scenario.ids],
        show_legend=True))
    first = faulted[0]
    estimate = fl.PlotPanel(title=f'uh{first}: Fhat_w vs the true lumped fault (rad/s^2)', config=fl.PlotConfig(
        paths=[fl.PlotSeries(value=_status(first, f'fault_estimate_attitude.{c}'), label=f'Fhat_w.{c}')
               for c in 'xyz']
        + [fl.PlotSeries(value=f'{topics.uh_topic(first, topics.FAULT_TRUTH)}.lumped_fault_attitude.{c}',
                         label=f'F_w.{c}') for c in 'xyz'],
        show_legend=True))
    scene = fl.ThreeDeePanel(title='team', config=fl.ThreeDeeConfig(
        follow_tf=frames.VIRTUAL_LEADER_FRAME, fixed_frame=frames.WORLD_FRAME))
    diagnostics = fl.DiagnosticsSummaryPanel(title='diagnostics', config=fl.DiagnosticsSummaryConfig(
        topic_to_render=topics.DIAGNOSTICS.name, sort_by_level=True))
    layout = fl.Layout(content=fl.SplitContainer(direction='row', items=[
        fl.SplitItem(proportion=3, content=scene),
        fl.SplitItem(proportion=2, content=fl.SplitContainer(direction='column', items=[
            fl.SplitItem(content=errors), fl.SplitItem(content=estimate),
            fl.SplitItem(content=diagnostics)]))]))
    return layout.to_json() + '\n'


def rviz_config(scenario) -> str:
    """Return an RViz2 configuration (YAML) of ``scenario``'s team.

    Fixed frame ``world``, grid, TF, ``/markers``, one Odometry display per UH, the view following
    the virtual leader.
    """
    displays = [
        {'Class': 'rviz_default_plugins/Grid', 'Name': 'Grid', 'Enabled': True, 'Cell Size': 5,
         'Plane Cell Count': 40, 'Reference Frame': frames.WORLD_FRAME},
        {'Class': 'rviz_default_plugins/TF', 'Name': 'TF', 'Enabled': True, 'Show Names': True,
         'Marker Scale': 3},
        {'Class': 'rviz_default_plugins/MarkerArray', 'Name': 'formation, hull, trails', 'Enabled': True,
         'Topic': {'Value': topics.MARKERS.name, 'Depth': 10, 'Reliability Policy': 'Reliable',
                   'Durability Policy': 'Volatile', 'History Policy': 'Keep Last'}},
    ]
    for i in scenario.ids:
        displays.append({
            'Class': 'rviz_default_plugins/Odometry', 'Name': f'uh{i} odometry', 'Enabled': True,
            'Keep': 50, 'Position Tolerance': 0.5, 'Angle Tolerance': 0.3,
            'Shape': {'Value': 'Arrow', 'Shaft Length': 1.5},
            'Topic': {'Value': topics.uh_topic(i, topics.ODOM), 'Depth': 10, 'Reliability Policy': 'Reliable',
                      'Durability Policy': 'Volatile', 'History Policy': 'Keep Last'}})
    config = {
        'Panels': [{'Class': 'rviz_common/Displays', 'Name': 'Displays'},
                   {'Class': 'rviz_common/Views', 'Name': 'Views'}],
        'Visualization Manager': {
            'Class': '', 'Enabled': True, 'Name': 'root', 'Displays': displays,
            'Global Options': {'Fixed Frame': frames.WORLD_FRAME, 'Background Color': '48; 48; 48',
                               'Frame Rate': 30},
            'Tools': [{'Class': 'rviz_default_plugins/Interact'}, {'Class': 'rviz_default_plugins/MoveCamera'}],
            'Views': {'Current': {'Class': 'rviz_default_plugins/Orbit', 'Name': 'follow the virtual leader',
                                  'Target Frame': frames.VIRTUAL_LEADER_FRAME, 'Distance': 60,
                                  'Pitch': 0.6, 'Yaw': 0.8}},
        },
    }
    return yaml.safe_dump(config, sort_keys=False)


def main(argv=None) -> int:
    """Write the Foxglove layout and RViz2 config of ``--scenario`` into ``--out``; return 0 (2: bad scenario)."""
    p = argparse.ArgumentParser(prog='python -m uh_bringup.views', description=__doc__.split('\n')[0])
    p.add_argument('--scenario', default='paper', help='scenario YAML, or "paper" (default)')
    p.add_argument('--out', default='views', help='directory to write the two files into (default views/)')
    args = p.parse_args(argv)
    try:
        scenario = load_scenario(args.scenario)
    except (OSError, ValueError) as exc:
        p.exit(2, f'{p.prog}: error: {exc}\n')
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / FOXGLOVE_FILE).write_text(foxglove_layout(scenario))
    (out / RVIZ_FILE).write_text(rviz_config(scenario))
    print(f'wrote {out / FOXGLOVE_FILE} and {out / RVIZ_FILE}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
