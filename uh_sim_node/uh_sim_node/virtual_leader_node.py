"""Virtual-leader node (``virtual_leader``): publishes the reference of docs/scenario.md on ``/reference``.

One message per ``/clock`` step, computed analytically at t_k = k dt.
"""
from __future__ import annotations

import uh_runtime as rt
from uh_core import frames
from uh_core.reference import VirtualLeaderReference
from uh_runtime import messages as m
from uh_wire import topics
from uh_wire.published import PublishedCounts
from uh_wire.run_config import declare_run_parameters, declare_view_parameters
from uh_wire.standard_msgs import tf_msg, transform_msg, view_publisher
from uh_wire.wire import clock_step, reference_to_msg

__all__ = ['VirtualLeaderNode', 'main']


class VirtualLeaderNode(rt.Node):
    """The virtual leader (see the module docstring); parameters: the run parameters.

    Keyword arguments go to ``Node`` (e.g. ``cli_args``, ``parameter_overrides``).
    """

    def __init__(self, **kwargs):
        super().__init__('virtual_leader', **kwargs)
        run = declare_run_parameters(self, per_uh=False)
        self.dt, self.last_step = run.dt, run.last_step
        self.reference = VirtualLeaderReference(run.scenario.reference)
        self.published_step = -1
        qos = topics.qos_profile(topics.STEP_QOS)
        self.pub = self.create_publisher(m.Reference, topics.REFERENCE.name, qos)
        self.views = declare_view_parameters(self, self.dt)
        self.published = PublishedCounts(topics.REFERENCE.name)
        if self.views.enabled:
            self.tf_pub = view_publisher(self, topics.TF)
        self.create_subscription(m.Clock, topics.CLOCK.name, self.on_clock, qos)

    def on_clock(self, msg) -> None:
        """Publish the reference of every step up to ``/clock``'s step k (at most the last step).

        Also the ``virtual_leader`` frame on ``/tf`` every ``pose_every`` steps when the views are on.
        """
        k = min(clock_step(msg, self.dt), self.last_step)
        # publish every step up to k (a realtime clock may skip ticks; lockstep never does)
        while self.published_step < k:
            self.published_step += 1
            t = self.published_step * self.dt
            ref = self.reference.at(t)
            self.pub.publish(reference_to_msg(self.published_step, t, ref))
            self.published.add(topics.REFERENCE.name)
            if self.views.enabled and self.published_step % self.views.pose_every == 0:
                # the reference's frame: its position and yaw (docs/visualization.md#frames)
                self.tf_pub.publish(tf_msg([transform_msg(
                    t, frames.WORLD_FRAME, frames.VIRTUAL_LEADER_FRAME, ref.position.tolist(),
                    frames.quaternion_from_euler_zyx(0.0, 0.0, float(ref.yaw)))]))
                self.published.add(topics.TF.name)

    def destroy_node(self):
        """Log the published counts; destroy the node."""
        if hasattr(self, 'published'):  # not when the constructor failed half-way
            rt.log_on_exit(self, self.published.line())
        return super().destroy_node()


def main(args=None):
    """Console script ``virtual_leader_node``: run :class:`VirtualLeaderNode` (:func:`uh_runtime.run_node`)."""
    rt.run_node(VirtualLeaderNode, args)


if __name__ == '__main__':
    main()
