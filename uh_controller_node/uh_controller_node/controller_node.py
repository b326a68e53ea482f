"""Controller node of one helicopter: ``controller`` in namespace ``/uhN``.

It subscribes to its own ``state``, to ``/uhj/state`` of exactly the UHs j with a_ij != 0 (its neighbours in the
scenario's graph, :mod:`uh_topology`), to ``/reference`` only if a_i0 != 0 and, with the safety filter on, to its own
``proximity`` (the filter's input, never the law's); it runs :class:`uh_controller_node.controller.UHController` and
publishes ``command`` and ``status``. Its parameters besides the run's: :mod:`uh_controller_node.node_parameters`.

Which inputs each step is computed from is decided by :class:`uh_controller_node.input_sync.InputSynchroniser`
(docs/reliability.md section 2): in ``lockstep`` step k waits for every input of step k (the run equals the
in-process one); in ``realtime`` own state k starts step k, computed when the step's inputs are in or after
``sync_wait`` wall s with the latest values (a one-shot timer; an idle controller checks every ``SLOW_POLL_S``).
The short wait matters: mixing step-k and step-(k-1) neighbour data makes z1 jitter by v dt (chattering).

Impairments (docs/campaigns.md#impairments, docs/runtime.md#impairments-in-real-time): the controller uses what
:mod:`~uh_controller_node.realtime_received` makes of its inputs and publishes them as delivered on ``received``.
Status and ``/diagnostics`` carry each neighbour's age (:class:`NeighbourAges`); in real time an age beyond the
team's delay margin (docs/delay.md#delay-margin) makes the report WARN. With ``events`` in the scenario
(docs/resilience.md) it also hears its standby neighbours and :class:`~uh_controller_node.loss_handling.NodeLosses`
detects, agrees on and answers losses.

Received messages carrying NaN/inf (or another UH's id) are rejected (logged, counted); the last valid one is kept
and ages. A stale input (realtime: ``stale_timeout`` simulated s behind, or unheard ``startup_grace`` wall s) is in
``ControllerStatus.stale_neighbours``, left out of the law (:meth:`UHController.step_degraded`): the UH follows the
others while they give it a path from the virtual leader, else holds. A restarted controller joins at once.
"""
from __future__ import annotations

import uh_runtime as rt
from uh_controller_node.controller import ControllerError, UHController, load_controller_kernels
from uh_controller_node.controller_diagnostics import ControllerDiagnostics, NeighbourAges
from uh_controller_node.delay_margin import MarginWatch
from uh_controller_node.input_sync import OWN, PROXIMITY, REFERENCE, InputSynchroniser
from uh_controller_node.loss_handling import NodeLosses
from uh_controller_node.node_parameters import GainParameters, declare_controller_parameters
from uh_controller_node.proximity_input import ProximityInput
from uh_controller_node.realtime_received import received_states_for
from uh_core import compiled_kernels
from uh_runtime import messages as m
from uh_wire import topics, wire
from uh_wire.published import PublishedCounts
from uh_wire.run_config import declare_run_parameters, declare_view_parameters
from uh_wire.standard_msgs import diagnostic_array_msg, view_publisher

__all__ = ['ControllerNode', 'main']

#: Period of the realtime check for a silent own state and the start-up grace, wall s.
SLOW_POLL_S = 0.1


class ControllerNode(rt.Node):
    """Controller of UH ``uh_id`` (parameter); see the module docstring for the behaviour."""

    def __init__(self, **kwargs):
        super().__init__('controller', **kwargs)
        run = declare_run_parameters(self)
        case, sync = declare_controller_parameters(self)
        self.uh_id, self.dt, self.case, scenario = run.uh_id, run.dt, case, run.scenario
        self.gains = GainParameters(self, scenario, case, self.uh_id)
        self.controller = UHController(self.uh_id, scenario, case=case, gains=self.gains.gains())
        self.add_on_set_parameters_callback(self.gains.check)
        self.add_post_set_parameters_callback(self._apply_gains)
        # load the law's and the fault isolator's numba kernels now, before the endpoints exist and the clock can start
        load_controller_kernels()
        # with events (docs/resilience.md) it also hears its standby neighbours, and tracks and answers losses
        self.losses = NodeLosses.of(self.controller, scenario, self.uh_id, self.dt, run.clock_mode)
        neighbours, linked = (self.losses.neighbours, self.losses.linked) if self.losses else (
            tuple(scenario.neighbours(self.uh_id)), scenario.leader_link(self.uh_id) > 0)
        # what this UH receives under the scenario's impairments (None without them)
        self.received = self.losses.received if self.losses else received_states_for(
            self.uh_id, neighbours, scenario, self.dt, run.clock_mode)
        self._arrive = getattr(self.received, 'arrive', None)   # realtime: every valid neighbour state is kept
        self.ages = NeighbourAges(neighbours, self.dt)
        sensed = self.controller.safety_enabled   # the safety filter's own input (docs/safety.md)
        self.sync = InputSynchroniser(self.uh_id, neighbours, linked, mode=run.clock_mode, dt=run.dt,
                                      last_step=run.last_step, reachable=self.controller.reachable_without,
                                      logger=self.get_logger(), sensed=sensed, **sync)
        self.proximity = ProximityInput(self.uh_id, self.controller.safety_parameters, self.dt)
        self.command_topic, self.status_topic, self.received_topic = (
            topics.uh_topic(self.uh_id, spec) for spec in (topics.COMMAND, topics.STATUS, topics.RECEIVED))
        self.published = PublishedCounts(self.command_topic, self.status_topic)
        qos = topics.qos_profile(topics.STEP_QOS)
        self.command_pub = self.create_publisher(m.ActuatorCommand, topics.COMMAND.name, qos)
        self.status_pub = self.create_publisher(m.ControllerStatus, topics.STATUS.name, qos)
        if self.received is not None:
            self.received_pub = self.create_publisher(m.ReceivedStates, topics.RECEIVED.name, qos)
        self.views = declare_view_parameters(self, self.dt)
        margin = MarginWatch(scenario, case) if run.clock_mode == 'realtime' else None
        self.diagnostics = ControllerDiagnostics(self.uh_id, self.views.diagnostics_every, self.views.diagnostics_phase(
            scenario.ids, self.uh_id, controller=True), safety=sensed, margin=margin)
        if self.views.enabled:
            self.diag_pub = view_publisher(self, topics.DIAGNOSTICS)
        self._subscribe(m.UHState, topics.STATE.name, qos, OWN, 'own state', wire.msg_to_state, self.uh_id)
        for j in neighbours:
            self._subscribe(m.UHState, topics.uh_topic(j, topics.STATE), qos, j, f'state of uh{j}',
                            wire.msg_to_state, j)
        if linked:
            self._subscribe(m.Reference, topics.REFERENCE.name, qos, REFERENCE, 'reference', wire.msg_to_reference)
        if sensed:
            self._subscribe(m.Proximity, topics.PROXIMITY.name, qos, PROXIMITY, 'proximity', wire.msg_to_proximity,
                            self.uh_id)
        self._deadline = None
        if run.clock_mode == 'realtime':
            # no busy polling: a one-shot timer armed only while a step waits for its neighbours'
            # data (sync_wait after its own state), and a slow one for silence and start-up checks
            self._deadline = self.create_timer(max(sync['sync_wait'], 0.0005), self._on_deadline)
            self._deadline.cancel()
            self.create_timer(SLOW_POLL_S, self._on_deadline)
        self.get_logger().info(f'uh{self.uh_id} ({case}, {run.clock_mode}): hears '
                               f"{', '.join(f'uh{j}' for j in neighbours) or 'no UH'}"
                               f"{' and the virtual leader' if linked else ''}"
                               f"{'; safety filter on' if sensed else ''}, {compiled_kernels.kernel_form()}")

    def _apply_gains(self, params) -> None:
        """Give the controller the gains of an accepted parameter change (docs/control_law.md)."""
        changed = self.gains.changed(params)
        if changed:
            self.controller.set_gains(self.gains.gains())
            self.get_logger().info('gains changed: ' + ', '.join(f'{p.name} = {p.value}' for p in changed))

    # -- inputs: offered to the synchroniser -------------------------------------------------------
    def _subscribe(self, msg_type, topic: str, qos, key, what: str, convert, *expected_id) -> None:
        """Subscribe to ``topic``: each message is converted and offered as input ``key`` (bad ones rejected)."""
        self.create_subscription(msg_type, topic, lambda msg: self._offer(key, msg, what, convert, *expected_id), qos)

    def _offer(self, key, msg, what: str, convert, *expected_id) -> None:
        try:
            value = convert(msg, *expected_id)
            if self.losses is not None and key not in (OWN, REFERENCE, PROXIMITY):
                self.losses.heard(key, int(msg.step), wire.msg_lost(msg))
        except wire.WireError as exc:
            self.sync.reject(what, exc)
            return
        if self._arrive is not None and key not in (OWN, REFERENCE, PROXIMITY):
            self._arrive(key, int(msg.step), value)
        self._compute(self.sync.offer(key, int(msg.step), value))
        if key == OWN and self._deadline is not None and self.sync.waiting is not None:
            self._deadline.reset()     # fires once, sync_wait from now, unless the step is released first

    def _on_deadline(self) -> None:
        """Release the step waited for with the latest data (realtime: it is due, or the slow check)."""
        self._deadline.cancel()
        self._compute(self.sync.poll())
        if self.sync.waiting is not None:   # still waiting (start-up grace): look again later
            self._deadline.reset()

    # -- stepping ----------------------------------------------------------------------------------
    def _compute(self, released) -> None:
        """Run the law on each released :class:`~uh_controller_node.input_sync.StepInputs`; publish."""
        for inputs in released:
            k = inputs.step
            own, neighbours = inputs.own, inputs.neighbours
            if self.received is not None:   # what this UH receives under the scenario's impairments
                own, neighbours = self.received.receive(k, own, neighbours)
            self.ages.add(k, neighbours, self.received, self.sync.lag)
            self.proximity.use(self.controller, inputs.proximity, k)
            try:
                if self.losses is not None:
                    u, status = self.losses.step(k, inputs, own, neighbours)
                elif inputs.stale:
                    u, status = self.controller.step_degraded(k, own, neighbours, inputs.reference,
                                                              self.dt, hold=inputs.hold)
                else:
                    u, status = self.controller.step(k, own, neighbours, inputs.reference, self.dt)
            except ControllerError as exc:  # inputs the law cannot use: no command this step, the node lives on
                self.get_logger().error(f'step {k} not computed: {exc}', throttle_duration_sec=1.0)
                self.diagnostics.not_computed()
                continue
            t, closest = k * self.dt, self.proximity.closest(own)
            self.command_pub.publish(wire.command_to_msg(self.uh_id, k, t, u, self.losses and self.losses.carried()))
            self.status_pub.publish(wire.status_to_msg(self.uh_id, k, t, status, inputs.stale_labels,
                                                       self.ages.overall(), closest))
            self.published.add(self.command_topic, self.status_topic)
            if self.received is not None:
                self.received_pub.publish(wire.received_states_to_msg(   # as delivered, not as predicted
                    self.uh_id, k, self.dt, own, self.received.delivered, self.received.sample_steps))
                self.published.add(self.received_topic)
            if self.views.enabled:
                report = self.diagnostics.add(k, inputs, status, self.sync, self.ages, closest)
                if report is not None:
                    self.diag_pub.publish(diagnostic_array_msg(t, [report]))
                    self.published.add(topics.DIAGNOSTICS.name)

    def destroy_node(self):
        """Log what the node published, rejected and how late its inputs were; destroy it."""
        if hasattr(self, 'published'):  # not when the constructor failed half-way
            rejected = self.sync.rejected_summary()
            rt.log_on_exit(self, self.published.line() + (f'; rejected inputs: {rejected}' if rejected else ''))
            lag = self.sync.lag_summary()
            if lag:
                rt.log_on_exit(self, lag)
        return super().destroy_node()


def main(args=None):
    """Run the controller node (entry point ``controller_node``)."""
    rt.run_node(ControllerNode, args)


if __name__ == '__main__':
    main()
