"""Simulator node of one helicopter: ``sim`` in namespace ``/uhN``.

Integrates the helicopter model (:mod:`uh_sim_node.helicopter`) from the commands it receives, applies the
scenario's fault schedule and faults injected at run time on ``fault``, and publishes ``state`` and ``fault_truth``
(topic registry: :mod:`uh_wire.topics`). Clock modes (docs/architecture.md#clock-modes):

- ``lockstep``: state 0 is published on ``/clock`` 0; every command k is integrated at once to state k+1 (the step's
  only input), with the fault truth of step k (state k, command k): the run equals the in-process one bit for bit.
- ``realtime``: on each ``/clock`` tick k the plant is integrated up to t_k with the latest command (zero-order
  hold, latest-value semantics) and state k is published.

Until its first command arrives the plant holds the hover trim. A UH lost by the scenario's ``events``
(docs/resilience.md) flies its failsafe from its event step on (it brakes to a hover), with zero fault
truth; each state carries the lost set of the command before it (the controller's, sent on to the team). An event
``stuck`` sticks its channel from its step on where the command before it left the actuator
(:meth:`~uh_sim_node.helicopter.HelicopterPlant.stick`), as an injection with ``stuck_in_place`` does at once.

Bad input never stops the plant: a command carrying NaN/inf or another UH's id is rejected (logged, counted) and the
last valid one kept; in realtime an older command than the one held is ignored, and one older than ``stale_timeout``
is reported once. A fault injection with rho outside [0, 1], a non-finite value, an unknown channel or another UH's
id is rejected (logged); rho = 0 (stuck actuator) is accepted with a warning that the controller cannot compensate it.
"""
from __future__ import annotations

import numpy as np

import uh_runtime as rt
from uh_core import compiled_kernels, diagnostics, frames
from uh_runtime import messages as m
from uh_sim_node import faults
from uh_sim_node.command_watch import CommandWatch
from uh_sim_node.faults import FaultError
from uh_sim_node.helicopter import hover_trim, plant_from_scenario
from uh_sim_node.plant_kernels import compile_plant_kernels
from uh_topology.events import silent_events
from uh_topology.losses import NEVER, failsafe_step
from uh_wire import run_config, topics
from uh_wire.published import PublishedCounts
from uh_wire.standard_msgs import diagnostic_array_msg, odometry_msg, tf_msg, transform_msg, view_publisher
from uh_wire.wire import WireError, clock_step, fault_truth_to_msg, msg_lost, msg_to_command, state_to_msg

__all__ = ['SimNode', 'main']


class SimNode(rt.Node):
    """Simulator of UH ``uh_id`` (parameter); see the module docstring for the behaviour."""

    def __init__(self, **kwargs):
        super().__init__('sim', **kwargs)
        run = run_config.declare_run_parameters(self)
        self.uh_id, self.scenario, self.mode = run.uh_id, run.scenario, run.clock_mode
        self.dt, self.last_step = run.dt, run.last_step
        self.plant = plant_from_scenario(self.scenario, self.uh_id)
        compile_plant_kernels()   # now, before the clock can start: a realtime run would lose those steps
        self.command = hover_trim(self.plant.params)
        self.step, self.published_step = 0, -1    # the state the plant holds, the last one published
        self.lost_step = next((e.step for e in silent_events(self.scenario.events) if e.uh == self.uh_id), NEVER)
        self.stuck = next((e for e in self.scenario.events if e.uh == self.uh_id and e.kind == 'stuck'), None)
        self.lost = {}                # the lost set the last command carried
        stale_timeout = run_config.declare_float_parameter(
            self, 'stale_timeout', run_config.DEFAULT_STALE_TIMEOUT, 60.0,
            'realtime: simulated seconds after which a held command is reported stale')
        self.watch = CommandWatch(self.uh_id, self.dt, max(1, int(round(stale_timeout / self.dt))),
                                  self.get_logger())
        self.views = run_config.declare_view_parameters(self, self.dt)
        self.diagnostics_phase = self.views.diagnostics_phase(self.scenario.ids, self.uh_id, controller=False)
        qos = topics.qos_profile(topics.STEP_QOS)
        self.state_pub = self.create_publisher(m.UHState, topics.STATE.name, qos)
        self.truth_pub = self.create_publisher(m.FaultTruth, topics.FAULT_TRUTH.name, qos)
        self.create_subscription(m.ActuatorCommand, topics.COMMAND.name, self.on_command, qos)
        self.create_subscription(m.Clock, topics.CLOCK.name, self.on_clock, qos)
        self.create_subscription(m.ActuatorFault, topics.FAULT.name, self.on_fault,
                                 topics.qos_profile(topics.FAULT.qos))
        self.state_topic, self.truth_topic, self.odom_topic = (
            topics.uh_topic(self.uh_id, spec) for spec in (topics.STATE, topics.FAULT_TRUTH, topics.ODOM))
        views = (topics.TF.name, self.odom_topic, topics.DIAGNOSTICS.name) if self.views.enabled else ()
        self.published = PublishedCounts(self.state_topic, self.truth_topic, *views)
        if self.views.enabled:
            self.tf_pub = view_publisher(self, topics.TF)
            self.odom_pub = view_publisher(self, topics.ODOM)
            self.diag_pub = view_publisher(self, topics.DIAGNOSTICS)
        self.get_logger().info(
            f'uh{self.uh_id}: {self.mode} mode, dt {self.dt} s, {self.last_step} steps, '
            f'{len(self.plant.faults)} scheduled fault(s), {compiled_kernels.kernel_form()}')

    # -- inputs -----------------------------------------------------------------------------------
    def on_clock(self, msg) -> None:
        """On ``/clock`` k: lockstep, publish state 0 once; realtime, integrate up to step k and publish."""
        k = clock_step(msg, self.dt)
        if self.mode == 'lockstep':
            if k == 0 and self.published_step < 0:
                self._publish_state()
            return
        # realtime: integrate with the latest command up to the tick (several steps if ticks were missed)
        while self.step < min(k, self.last_step):
            self._integrate_one_step()
        if self.step > self.published_step:
            self._publish_state()

    def on_command(self, msg) -> None:
        """Take a command (invalid: rejected, the last valid kept); lockstep: integrate to k+1 and publish."""
        try:
            u, lost = msg_to_command(msg, expected_id=self.uh_id), msg_lost(msg)
        except WireError as exc:
            self.watch.rejected += 1
            self.get_logger().error(f'rejected command: {exc}; keeping the last valid command '
                                    f'({self.watch.rejected} rejected so far)', throttle_duration_sec=1.0)
            return
        k = int(msg.step)
        if self.stuck is not None and k == self.stuck.step == self.step:   # stuck where the last command left it
            self.get_logger().warn(f'event: {self.plant.stick(self.stuck.channel, self.command, k * self.dt)}')
        if self.mode != 'lockstep' and k < self.watch.command_step:
            return  # older than the command held: reordered, or replayed history after a controller restart
        self.command, self.lost = u, lost
        self.watch.taken(k, self.step)
        if self.mode != 'lockstep':
            if k == self.last_step == self.step:  # the final step's truth, as in lockstep
                self._publish_truth(k)
            return
        if k != self.step:
            self.get_logger().warn(f'ignored command for step {k}: the plant is at step {self.step}')
            return
        if k < self.last_step:
            self._integrate_one_step()
            self._publish_state()
        else:  # the last step: its fault truth completes the record, the plant stops here
            self._publish_truth(self.step)

    def on_fault(self, msg) -> None:
        """Run-time fault injection (uh_msgs/ActuatorFault); invalid ones are rejected and logged."""
        try:
            fault = faults.inject(self.plant, msg, self.uh_id, self.command, self.step * self.dt)
        except FaultError as exc:
            self.get_logger().error(f'rejected fault injection: {exc}; the plant keeps its current faults')
            self.watch.rejected_faults += 1
            return
        self.get_logger().warn(f'fault injected on uh{self.uh_id}: {fault}')
        if fault.is_stuck:
            self.get_logger().warn(f'rho = 0 on channel {fault.channel}: the actuator is stuck, which is outside '
                                   'what the controller can compensate (the fault truth reports it as stuck)')

    # -- outputs ----------------------------------------------------------------------------------
    def _integrate_one_step(self) -> None:
        self.watch.integrating(self.step)
        self._publish_truth(self.step)
        if self.step < self.lost_step:
            self.plant.step(self.command, self.step * self.dt, self.dt)
        else:   # lost: the failsafe brakes it to a hover (uh_topology.losses.failsafe_step)
            x = self.plant.x
            failsafe_step(x, self.dt, self.scenario.safety.brake_accel)
            self.plant.reset(x)
        self.step += 1

    def _publish_truth(self, k: int) -> None:
        t = k * self.dt
        f_p, f_w = self.plant.lumped_faults(self.command, t) if k < self.lost_step else (np.zeros(3), np.zeros(3))
        u_actual = self.plant.actual_inputs(self.command, t)
        self.truth_pub.publish(fault_truth_to_msg(self.uh_id, k, t, f_p, f_w, u_actual,
                                                  self.plant.fault_active(t), self.plant.stuck(t)))
        self.published.add(self.truth_topic)

    def _publish_state(self) -> None:
        t = self.step * self.dt
        self.state_pub.publish(state_to_msg(self.uh_id, self.step, t, self.plant.x, self.lost))
        self.published_step = self.step
        self.published.add(self.state_topic)
        if self.views.enabled:
            self._publish_views(t)

    def _publish_views(self, t: float) -> None:
        """Publish /tf and odom every ``views.pose_every`` steps, /diagnostics every ``views.diagnostics_every``."""
        x = self.plant.x
        if self.step % self.views.pose_every == 0:
            pose = frames.pose_of_state(x)
            self.tf_pub.publish(tf_msg([transform_msg(t, frames.WORLD_FRAME, frames.base_link(self.uh_id), *pose)]))
            self.odom_pub.publish(odometry_msg(self.uh_id, t, x, pose))
            self.published.add(topics.TF.name, self.odom_topic)
        if self.step % self.views.diagnostics_every == self.diagnostics_phase:
            window = self.watch.window(self.step, self.plant.fault_active(t), self.plant.stuck(t))
            self.diag_pub.publish(diagnostic_array_msg(t, [diagnostics.simulator_diagnostic(self.uh_id, window)]))
            self.published.add(topics.DIAGNOSTICS.name)

    def destroy_node(self):
        """Log the published counts (and late or rejected commands); destroy the node."""
        if hasattr(self, 'published'):  # not when the constructor failed half-way
            rt.log_on_exit(
                self, self.published.line()
                + (f'; late commands: {self.watch.late_commands}' if self.mode == 'realtime' else '')
                + (f'; rejected commands: {self.watch.rejected}' if self.watch.rejected else ''))
        return super().destroy_node()


def main(args=None):
    """Run :class:`SimNode` (the ``sim_node`` console script is :func:`uh_sim_node.entry_points.sim_node`)."""
    rt.run_node(SimNode, args)


if __name__ == '__main__':
    main()
