"""Visualisation node (``visualization``): ``visualization_msgs/MarkerArray`` on ``/markers``.

For RViz2 or Foxglove, live or from the bag, in the fixed frame ``world`` (z up):

- ``uh``: one arrow per helicopter along its body x axis (leaders blue, followers green);
- ``label``: the UH's name above it;
- ``trail``: the last ``trail_length`` published positions of each UH (line strip);
- ``formation``: the leaders' polygon (closed line strip, leader order);
- ``hull``: the leaders' convex hull as a translucent triangle fan (exact for three leaders, the
  paper's case: the hull of three points is their triangle);
- ``target``: each follower's containment target sum_j w_kj p_j (docs/graph.md);
- ``virtual_leader``: the reference position p0.

It publishes every ``period_steps`` steps, once the states of every UH (and the reference) of
that step are in, so a lockstep run records the same markers every time.
"""
from __future__ import annotations

import math

import numpy as np

import uh_runtime as rt
from uh_core.layout import X_P_SLICE, X_THETA_SLICE
from uh_runtime import messages as m
from uh_wire import topics
from uh_wire.published import PublishedCounts
from uh_wire.run_config import declare_run_parameters
from uh_wire.wire import WireError, msg_to_state, stamp

__all__ = ['VisualizationNode', 'main']

LEADER_RGBA = (0.15, 0.4, 0.95, 1.0)
FOLLOWER_RGBA = (0.1, 0.75, 0.3, 1.0)


def _color(rgba):
    c = m.ColorRGBA()
    c.r, c.g, c.b, c.a = (float(v) for v in rgba)
    return c


def _point(p):
    pt = m.Point()
    pt.x, pt.y, pt.z = (float(v) for v in p[:3])
    return pt


def _yaw_pitch_roll_quaternion(phi, theta, psi):
    """Quaternion (x, y, z, w) of R = Rz(psi) Ry(theta) Rx(phi)."""
    cr, sr = math.cos(phi / 2), math.sin(phi / 2)
    cp, sp = math.cos(theta / 2), math.sin(theta / 2)
    cy, sy = math.cos(psi / 2), math.sin(psi / 2)
    return (sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy)


class VisualizationNode(rt.Node):
    """The ``visualization`` node (see the module docstring).

    Parameters (ROS): the run parameters, ``period_steps`` and ``trail_length``. Keyword arguments go
    to ``Node`` (e.g. ``cli_args``, ``parameter_overrides``).
    """

    def __init__(self, **kwargs):
        super().__init__('visualization', **kwargs)
        run = declare_run_parameters(self, per_uh=False)
        self.declare_parameter('period_steps', 10, rt.ParameterDescriptor(
            description='publish markers every this many steps', read_only=True,
            integer_range=[rt.IntegerRange(from_value=1, to_value=100000, step=1)]))
        self.declare_parameter('trail_length', 200, rt.ParameterDescriptor(
            description='positions kept in each trail (one per published step)', read_only=True,
            integer_range=[rt.IntegerRange(from_value=2, to_value=100000, step=1)]))
        self.scenario, self.dt = run.scenario, run.dt
        self.period = int(self.get_parameter('period_steps').value)
        self.trail_length = int(self.get_parameter('trail_length').value)
        self.ids = tuple(self.scenario.ids)
        self.weights = np.asarray(self.scenario.containment_weights)
        self.states: dict[int, dict[int, np.ndarray]] = {}   # step -> {uh: state}
        self.references: dict[int, np.ndarray] = {}
        self.trails = {i: [] for i in self.ids}
        qos = topics.qos_profile(topics.STEP_QOS)
        self.pub = self.create_publisher(m.MarkerArray, topics.MARKERS.name, topics.qos_profile(topics.MARKERS.qos))
        self.published = PublishedCounts(topics.MARKERS.name)
        for i in self.ids:
            self.create_subscription(m.UHState, topics.uh_topic(i, topics.STATE),
                                     lambda msg, i=i: self.on_state(i, msg), qos)
        self.create_subscription(m.Reference, topics.REFERENCE.name, self.on_reference, qos)

    def on_state(self, uh_id: int, msg) -> None:
        """Keep UH ``uh_id``'s state of a marker step (every ``period_steps``); publish the step once complete."""
        k = int(msg.step)
        if k % self.period:
            return
        try:
            self.states.setdefault(k, {})[uh_id] = msg_to_state(msg, expected_id=uh_id)
        except WireError as exc:
            self.get_logger().warn(f'ignored state: {exc}')
            return
        self._publish_ready(k)

    def on_reference(self, msg) -> None:
        """Keep the reference position of a marker step; publish the step once complete."""
        k = int(msg.step)
        if k % self.period == 0:
            self.references[k] = np.array([msg.position.x, msg.position.y, msg.position.z])
            self._publish_ready(k)

    def _publish_ready(self, k: int) -> None:
        if len(self.states.get(k, ())) < len(self.ids) or k not in self.references:
            return
        states, p0 = self.states.pop(k), self.references.pop(k)
        for old in [s for s in self.states if s < k]:
            del self.states[old]
        self.pub.publish(self.markers(k, states, p0))
        self.published.add(topics.MARKERS.name)

    def markers(self, k: int, states: dict, p0: np.ndarray):
        """Return the MarkerArray of step ``k`` from the UH states {id: (12,)} and the reference position."""
        t = stamp(k * self.dt)
        out = m.MarkerArray()
        markers = []

        def marker(ns, mid, mtype, rgba, scale):
            mk = m.Marker()
            mk.header.stamp, mk.header.frame_id = t, 'world'
            mk.ns, mk.id, mk.type, mk.action = ns, int(mid), int(mtype), 0  # ADD
            mk.pose.orientation.w = 1.0
            mk.scale.x, mk.scale.y, mk.scale.z = (float(v) for v in scale)
            mk.color = _color(rgba)
            markers.append(mk)
            return mk

        leaders = [i for i in self.ids if self.scenario.is_leader(i)]
        followers = [i for i in self.ids if not self.scenario.is_leader(i)]
        for i in self.ids:
            x = states[i]
            rgba = LEADER_RGBA if i in leaders else FOLLOWER_RGBA
            arrow = marker('uh', i, 0, rgba, (1.0, 0.25, 0.25))  # ARROW
            arrow.pose.position = _point(x[X_P_SLICE])
            q = _yaw_pitch_roll_quaternion(*x[X_THETA_SLICE])
            arrow.pose.orientation.x, arrow.pose.orientation.y, arrow.pose.orientation.z, arrow.pose.orientation.w = q
            label = marker('label', i, 9, (1, 1, 1, 1), (0, 0, 0.5))  # TEXT_VIEW_FACING
            label.pose.position = _point(x[X_P_SLICE] + np.array([0.0, 0.0, 0.6]))
            label.text = f'uh{i}'
            trail = self.trails[i]
            trail.append(_point(x[X_P_SLICE]))   # the trail keeps its Point messages: one new Point per publication
            del trail[:-self.trail_length]
            line = marker('trail', i, 4, rgba[:3] + (0.6,), (0.05, 0, 0))  # LINE_STRIP
            line.points = list(trail)
        if len(leaders) >= 2:
            poly = marker('formation', 0, 4, LEADER_RGBA, (0.05, 0, 0))
            poly.points = [_point(states[i]) for i in leaders + leaders[:1]]
        if len(leaders) >= 3:
            hull = marker('hull', 0, 11, LEADER_RGBA[:3] + (0.2,), (1, 1, 1))  # TRIANGLE_LIST
            first = states[leaders[0]]
            hull.points = [_point(p) for a, b in zip(leaders[1:-1], leaders[2:], strict=True)
                           for p in (first, states[a], states[b])]
        lead_pos = np.array([states[i][X_P_SLICE] for i in leaders])
        for row, k_id in enumerate(followers):
            target = marker('target', k_id, 2, FOLLOWER_RGBA[:3] + (0.5,), (0.3, 0.3, 0.3))  # SPHERE
            target.pose.position = _point(self.weights[row] @ lead_pos)
        vl = marker('virtual_leader', 0, 2, (0.9, 0.2, 0.2, 1.0), (0.4, 0.4, 0.4))
        vl.pose.position = _point(p0)
        out.markers = markers
        return out

    def destroy_node(self):
        """Log what the node published; destroy it."""
        if hasattr(self, 'published'):  # not when the constructor failed half-way
            rt.log_on_exit(self, self.published.line())
        return super().destroy_node()


def main(args=None):
    """Console script ``visualization_node``: run :class:`VisualizationNode` (:func:`uh_runtime.run_node`)."""
    rt.run_node(VisualizationNode, args)


if __name__ == '__main__':
    main()
