"""The one registry of topic names, message types and QoS of the UH stack.

Per-UH topics are relative names resolved in the UH's namespace ``/uhN`` (so ``-r __ns:=/uh3``
and remaps work); team-wide topics are absolute. Nodes, the recorder, the run script, the
documentation table (docs/topics.md) and the subscription audit all read this module.

QoS (ROS 2 profiles):

- per-step data (state, command, status, fault truth, reference, clock): reliable, keep-last
  ``STEP_DEPTH``, transient-local. Transient-local makes the start of a lockstep run immune to
  discovery order (a reader matched late still receives the first steps), and the depth bounds how
  far the recorder may lag behind before the lockstep clock waits for it (``RECORDER_LAG_STEPS``).
- fault injection: reliable, keep-last 10, volatile (an injection is an event, not state).
- the standard views for generic tools (``/tf``, ``odom``, ``/diagnostics``; docs/visualization.md):
  reliable, transient-local, keep-last ``STEP_DEPTH``; ``/markers`` the same with depth 10 (one
  message every 10 steps). A transient-local writer matches the volatile readers of RViz2, tf2 and
  Foxglove (they get no history), and a recorder whose reader matched a writer a few steps after
  its first sample still receives that sample: the first steps of a view are recorded whatever the
  order of discovery (the lockstep clock starts only once the recorder has subscribed to every
  topic of :func:`run_topics`, and it lags at most ``RECORDER_LAG_STEPS``).
"""
from __future__ import annotations

from dataclasses import dataclass

from uh_runtime.dds.qos import QoSWords, profile_from_words
from uh_runtime.names import RECORDER_PROGRESS_TOPIC

__all__ = [
    'QosSpec', 'TopicSpec', 'STEP_QOS', 'EVENT_QOS', 'STEP_DEPTH', 'RECORDER_LAG_STEPS',
    'STATE', 'COMMAND', 'STATUS', 'FAULT_TRUTH', 'FAULT', 'REFERENCE', 'CLOCK', 'MARKERS',
    'RECORDER_PROGRESS', 'VIEW_QOS', 'MARKER_QOS', 'VIEWS', 'run_topics',
    'TF', 'ODOM', 'DIAGNOSTICS', 'RECEIVED', 'PROXIMITY', 'PER_UH', 'IMPAIRED_PER_UH', 'SAFETY_PER_UH',
    'scenario_flags',
    'TEAM', 'uh_namespace',
    'uh_topic', 'team_topics', 'qos_profile',
]

#: History depth of per-step topics: how many steps a slow reader may fall behind without loss.
STEP_DEPTH = 100
#: How many steps the recorder may lag behind the lockstep clock (must stay below STEP_DEPTH).
RECORDER_LAG_STEPS = 40


#: A ROS 2 QoS profile as plain data (policy names as in rosbag2's metadata): the runtime's record.
QosSpec = QoSWords


@dataclass(frozen=True)
class TopicSpec:
    """A topic of the registry.

    Its name (relative = in the UH's namespace), ROS type, QoS, whether it carries one message per
    lockstep step, and who publishes/subscribes (for documentation and audits).
    """

    name: str
    type: str
    qos: QosSpec
    per_step: bool
    publisher: str
    subscribers: str
    description: str


STEP_QOS = QosSpec('reliable', 'transient_local', 'keep_last', STEP_DEPTH)
EVENT_QOS = QosSpec('reliable', 'volatile', 'keep_last', 10)
VIEW_QOS = QosSpec('reliable', 'transient_local', 'keep_last', STEP_DEPTH)
#: /markers: one MarkerArray every 10 steps, so 10 of them cover the recorder's allowed lag
MARKER_QOS = QosSpec('reliable', 'transient_local', 'keep_last', 10)

STATE = TopicSpec('state', 'uh_msgs/msg/UHState', STEP_QOS, True, 'sim (own UH)',
                  'controller of the same UH and of every UH that hears it; recorder',
                  'helicopter state at step k')
COMMAND = TopicSpec('command', 'uh_msgs/msg/ActuatorCommand', STEP_QOS, True, 'controller',
                    'sim of the same UH; lockstep clock; recorder', 'actuator command for step k')
STATUS = TopicSpec('status', 'uh_msgs/msg/ControllerStatus', STEP_QOS, True, 'controller', 'recorder',
                   'controller internals: errors, estimates, saturation, cost rate')
FAULT_TRUTH = TopicSpec('fault_truth', 'uh_msgs/msg/FaultTruth', STEP_QOS, True, 'sim', 'recorder',
                        'true lumped faults (never read by a controller)')
FAULT = TopicSpec('fault', 'uh_msgs/msg/ActuatorFault', EVENT_QOS, False, 'inject_fault (user)',
                  'sim of the same UH; recorder', 'actuator-fault injection at run time')
REFERENCE = TopicSpec('/reference', 'uh_msgs/msg/Reference', STEP_QOS, True, 'virtual_leader',
                      'controllers of leaders with a_i0 > 0; recorder', 'virtual-leader reference at step k')
CLOCK = TopicSpec('/clock', 'rosgraph_msgs/msg/Clock', STEP_QOS, True, 'clock',
                  'sims, virtual leader; recorder', 'simulation time, one message per step')
MARKERS = TopicSpec('/markers', 'visualization_msgs/msg/MarkerArray', MARKER_QOS, False, 'visualization',
                    'RViz2 / Foxglove; recorder',
                    'helicopter poses, trails, formation polygon, convex hull, containment targets (frame world)')
RECORDER_PROGRESS = TopicSpec(RECORDER_PROGRESS_TOPIC, 'builtin_interfaces/msg/Time', EVENT_QOS, False,
                              'recorder', 'lockstep clock',
                              'sim time up to which every per-step topic has been written to the bag')

TF = TopicSpec('/tf', 'tf2_msgs/msg/TFMessage', VIEW_QOS, False, 'sims, virtual_leader',
               'RViz2, tf2, Foxglove; recorder',
               'world -> uhN/base_link of every UH, world -> virtual_leader (REP 103/105 frames)')
ODOM = TopicSpec('odom', 'nav_msgs/msg/Odometry', VIEW_QOS, False, 'sim',
                 'RViz2, PlotJuggler, Foxglove; recorder',
                 'pose in world, twist in uhN/base_link (the state for generic tools)')
DIAGNOSTICS = TopicSpec('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray', VIEW_QOS, False,
                        'sims, controllers', 'rqt_robot_monitor, Foxglove; recorder',
                        'OK/WARN/ERROR of every simulator and controller, a few times per simulated second')

RECEIVED = TopicSpec('received', 'uh_msgs/msg/ReceivedStates', STEP_QOS, True, 'controller (impaired runs)',
                     'recorder', 'the own and neighbour states the controller received for step k, after the '
                     'scenario\'s delay, jitter, loss, dropout and noise, before any prediction '
                     '(docs/campaigns.md#impairments)')

PROXIMITY = TopicSpec('proximity', 'uh_msgs/msg/Proximity', STEP_QOS, True, 'sensing (safety filter on)',
                      'controller of the same UH (its safety filter only); recorder',
                      'every other UH within the safety filter\'s sensing radius at step k, as onboard sensing or '
                      'a beacon would report it (docs/safety.md#what-the-filter-knows)')

PER_UH = (STATE, COMMAND, STATUS, FAULT_TRUTH, FAULT, ODOM)
#: Per-UH topics of a run whose scenario has impairments, besides PER_UH.
IMPAIRED_PER_UH = (RECEIVED,)
#: Per-UH topics of a run with the safety filter on, besides PER_UH.
SAFETY_PER_UH = (PROXIMITY,)
TEAM = (REFERENCE, CLOCK, TF, DIAGNOSTICS)
#: The standard views: published unless a run switches them off (``standard_views``).
VIEWS = (TF, ODOM, DIAGNOSTICS)


def uh_namespace(uh_id: int) -> str:
    """Namespace of UH ``uh_id``: ``/uh<id>``."""
    return f'/uh{int(uh_id)}'


def uh_topic(uh_id: int, spec: TopicSpec) -> str:
    """Fully qualified name of a per-UH topic, e.g. ``uh_topic(2, STATE) == '/uh2/state'``."""
    if spec.name.startswith('/'):
        return spec.name
    return f'{uh_namespace(uh_id)}/{spec.name}'


def team_topics(uh_ids, impaired: bool = False, safety: bool = False) -> list[tuple[str, TopicSpec]]:
    """Return every recorded topic of a team with UHs ``uh_ids`` as ``[(full name, spec), ...]``.

    With ``impaired``, the topics of a scenario with impairments; with ``safety``, those of a run
    whose safety filter is on (:func:`scenario_flags` gives both for a scenario).
    """
    topics = [(spec.name, spec) for spec in TEAM]
    per_uh = PER_UH + (IMPAIRED_PER_UH if impaired else ()) + (SAFETY_PER_UH if safety else ())
    for uh_id in sorted(uh_ids):
        topics += [(uh_topic(uh_id, spec), spec) for spec in per_uh]
    return topics


def scenario_flags(scenario) -> dict:
    """Return the keyword arguments of :func:`team_topics` for ``scenario``: ``{'impaired': ..., 'safety': ...}``.

    A scenario with ``events`` or ``resilience`` counts as impaired: its controllers receive through the
    links' rule (a lost UH dropped, docs/resilience.md) and publish what they used on ``received``.
    """
    impaired = (scenario.impairments is not None or bool(getattr(scenario, 'events', ()))
                or getattr(scenario, 'resilience', None) is not None)
    return {'impaired': impaired, 'safety': bool(scenario.safety.enabled)}


def run_topics(uh_ids, impaired: bool = False, views: bool = True,
               visualization: bool = True, safety: bool = False) -> list[tuple[str, TopicSpec]]:
    """Return every topic a run's nodes publish, or subscribe to for the recorder, as ``[(full name, spec), ...]``.

    :func:`team_topics`, without the standard views when ``views`` is False, with ``/markers``
    when the run has its visualisation node. These are the topics the recorder must have
    subscribed to before the lockstep clock publishes step 0 (uh_sim_node.clock_node).
    """
    topics = [(name, spec) for name, spec in team_topics(uh_ids, impaired, safety) if views or spec not in VIEWS]
    return topics + ([(MARKERS.name, MARKERS)] if visualization else [])


def qos_profile(spec: QosSpec):
    """Build the node runtime's ``QoSProfile`` (rclpy's on a ROS 2 machine) from ``spec``.

    See :func:`uh_runtime.dds.qos.profile_from_words`.
    """
    return profile_from_words(spec)
