"""The ready-made views in views/ (docs/visualization.md#ready-made-views).

They are generated from the paper scenario by uh_bringup.views, in sync with it, and name only topics and frames the
team has.
"""
import json
import re
from pathlib import Path

import pytest
import yaml

from uh_bringup import views
from uh_core import frames
from uh_wire import topics

ROOT = Path(__file__).resolve().parents[1]
pytest.importorskip('foxglove', reason='the Foxglove layout is built with foxglove-sdk')


def _team_topics(scenario):
    names = {name for name, _ in topics.team_topics(scenario.ids)}
    return names | {topics.MARKERS.name}


def test_the_committed_views_are_what_the_generator_writes(paper):
    assert (ROOT / 'views' / views.FOXGLOVE_FILE).read_text() == views.foxglove_layout(paper)
    assert (ROOT / 'views' / views.RVIZ_FILE).read_text() == views.rviz_config(paper)


def test_the_foxglove_layout_plots_fields_of_the_teams_topics(paper):
    layout = json.loads(views.foxglove_layout(paper))
    text = json.dumps(layout)
    panels = re.findall(r'"panelType": "(\w+)"', text)
    assert panels == ['ThreeDee', 'Plot', 'Plot', 'DiagnosticsSummary']
    paths = re.findall(r'"value": "(/[^"]+)"', text)
    assert paths and {p.split('.')[0] for p in paths} <= _team_topics(paper)
    assert '"followTf": "virtual_leader"' in text and '"fixedFrame": "world"' in text
    assert f'"topicToRender": "{topics.DIAGNOSTICS.name}"' in text


def test_the_rviz_config_shows_every_uhs_odometry_in_world(paper):
    config = yaml.safe_load(views.rviz_config(paper))['Visualization Manager']
    assert config['Global Options']['Fixed Frame'] == frames.WORLD_FRAME
    shown = [d['Topic']['Value'] for d in config['Displays'] if 'Topic' in d]
    assert set(shown) <= _team_topics(paper)
    assert {f'/uh{i}/odom' for i in paper.ids} <= set(shown) and '/markers' in shown
    assert config['Views']['Current']['Target Frame'] == frames.VIRTUAL_LEADER_FRAME
