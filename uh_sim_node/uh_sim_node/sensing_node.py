"""Sensing node (``sensing``): each UH's proximity input for the safety filter, on ``/uhN/proximity``.

It stands for the world's physics the way a simulator's sensor system does: onboard sensing or a
broadcast beacon (docs/safety.md#what-the-filter-knows). It hears every ``/uhN/state`` and
publishes, per UH and step, a ``uh_msgs/Proximity`` with the state of every other UH within the
scenario's ``safety.sensing_radius``: O(N) messages per step for the team. What each message holds
and when it is due is :class:`uh_sim_node.sensing.ProximitySensing` (lockstep: once a step's states
are all in, so the run equals the in-process one bit for bit; realtime: on each UH's own state, with
the newest of the others; a silent UH stays an obstacle at its last state).

A run starts it only when the safety filter is on (``safety`` parameter or the scenario's
``safety.enabled``); started with the filter off it exits with one line saying so. A state carrying
NaN/inf or another UH's id is rejected (logged at most once a second per UH, with a count); the last
valid state is kept.
"""
from __future__ import annotations

import uh_runtime as rt
from uh_runtime import messages as m
from uh_sim_node.sensing import ProximitySensing
from uh_wire import topics
from uh_wire.published import PublishedCounts
from uh_wire.run_config import RunConfigError, declare_run_parameters
from uh_wire.wire import WireError, msg_to_state, proximity_to_msg

__all__ = ['SensingNode', 'main']


class SensingNode(rt.Node):
    """The team's proximity sensing (see the module docstring); parameters: the run parameters.

    Keyword arguments go to ``Node`` (e.g. ``cli_args``, ``parameter_overrides``).
    """

    def __init__(self, **kwargs):
        super().__init__('sensing', **kwargs)
        run = declare_run_parameters(self, per_uh=False)
        safety = run.scenario.safety
        if not safety.enabled:
            raise RunConfigError(f'scenario {run.scenario.name!r} runs without the safety filter (safety.enabled: '
                                 'false), so no UH reads a proximity input; start the sensing node with '
                                 '-p safety:=on, or not at all')
        self.dt, self.sensing_radius = run.dt, float(safety.sensing_radius)
        self.sensing = ProximitySensing(run.scenario.ids, self.sensing_radius, run.clock_mode == 'lockstep',
                                        run.last_step)
        self.rejected: dict[int, int] = {}
        qos = topics.qos_profile(topics.STEP_QOS)
        names = {i: topics.uh_topic(i, topics.PROXIMITY) for i in run.scenario.ids}
        self.pubs = {i: self.create_publisher(m.Proximity, name, qos) for i, name in names.items()}
        self.published = PublishedCounts(*names.values())
        self.names = names
        for i in run.scenario.ids:
            self.create_subscription(m.UHState, topics.uh_topic(i, topics.STATE),
                                     lambda msg, i=i: self.on_state(i, msg), qos)
        self.get_logger().info(f'{len(names)} UHs, sensing radius {self.sensing_radius:g} m, {run.clock_mode}')

    def on_state(self, uh_id: int, msg) -> None:
        """Take UH ``uh_id``'s state (bad ones rejected); publish the proximity messages now due."""
        try:
            state = msg_to_state(msg, uh_id)
        except WireError as exc:
            count = self.rejected[uh_id] = self.rejected.get(uh_id, 0) + 1
            self.get_logger().error(f'rejected state of uh{uh_id}: {exc}; keeping the last valid one '
                                    f'({count} rejected so far)', throttle_duration_sec=1.0)
            return
        # the received message travels on as it is (the states are republished unchanged)
        for report in self.sensing.offer(uh_id, int(msg.step), state, msg):
            self.pubs[report.uh_id].publish(proximity_to_msg(report, self.dt, self.sensing_radius))
            self.published.add(self.names[report.uh_id])

    def destroy_node(self):
        """Log the published counts and rejected states; destroy the node."""
        if hasattr(self, 'published'):  # not when the constructor failed half-way
            rejected = ', '.join(f'uh{i} {n}' for i, n in sorted(self.rejected.items()))
            rt.log_on_exit(self, self.published.line() + (f'; rejected states: {rejected}' if rejected else ''))
        return super().destroy_node()


def main(args=None):
    """Console script ``sensing_node``: run :class:`SensingNode` (:func:`uh_runtime.run_node`)."""
    rt.run_node(SensingNode, args)


if __name__ == '__main__':
    main()
