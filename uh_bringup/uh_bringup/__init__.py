"""Bring-up of a team run (docs/architecture.md, docs/ros2.md).

``team_nodes``: the one table of a team's nodes; ``run_formation`` (``uh-run-formation``) with
``run_checks``, ``run_setup``, ``run_processes``, ``run_watch``, ``run_outcome``, ``supervisor`` and
``netns``: a team run as one process per node; ``launch_run``: what the ROS 2 launch file
(``launch/formation.launch.py``) does around the nodes; ``composed``: several nodes in one process;
``inject_fault`` (``uh-inject-fault``), ``compare`` (``scripts/compare.sh``) and ``views`` (Foxglove
and RViz2 views of a team).
"""
