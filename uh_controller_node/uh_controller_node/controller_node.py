"""Controller node of one helicopter: ``controller`` in namespace ``/uhN``.

It subscribes to its own ``state``, to ``/uhj/state`` of exactly the UHs j with a_ij != 0 (its
neighbours in the scenario's graph, :mod:`uh_topology`), and to ``/reference`` only if a_i0 != 0,
runs :class:`uh_controller_node.controller.UHController` and publishes ``command`` and ``status``.

The node converts messages (:mod:`uh_wire.wire`) and publishes; which inputs each step is computed
from is decided by :class:`uh_controller_node.input_sync.InputSynchroniser` (docs/reliability.md
section 2):

- ``lockstep``: step k is computed once the own state k, every neighbour's state k and (if linked)
  reference k have arrived, in step order, so the run reproduces the in-process reference
  simulation exactly.
- ``realtime``: each own state k starts step k. It is computed as soon as every neighbour's state
  and the reference of the same step are in, or after ``sync_wait`` wall seconds with the latest
  values received (latest-value semantics): a one-shot timer is armed when the own state arrives
  and the step cannot be computed yet, so an idle controller wakes only for messages and a slow
  check every ``SLOW_POLL_S``. The short wait matters: the sims publish step k at the
  same tick, and mixing step-k and step-(k-1) neighbour data makes the consensus error jitter by
  v dt, which the command filters' derivatives amplify into chattering commands.

Impairments (docs/campaigns.md#impairments): when the scenario has them, the controller uses what
:class:`~uh_controller_node.impairments.ReceivedStates` makes of the released states (delay, loss,
dropout, noise; the same functions as the in-process run) and publishes it on ``received``, so a
bag shows what each controller actually got. They are defined on control steps: lockstep only.

Received messages carrying NaN/inf (or another UH's id) are rejected: the node logs the reason
(at most once a second per input, with a count) and keeps its last valid input, which then ages
like a silent neighbour.

Stale data (realtime only; lockstep waits for every input by construction): a neighbour's state or
the reference whose newest valid step is more than ``stale_timeout`` simulated seconds behind the
step being computed is *stale*. It is listed in ``ControllerStatus.stale_neighbours`` (``uhJ`` or
``reference``) and left out of the control law (:meth:`UHController.step_degraded`): the UH keeps
following the remaining neighbours while the remaining graph still gives it a path from the virtual
leader (Assumption 1, docs/graph.md; :meth:`UHController.reachable_without`), and holds the position
and yaw it had when that stopped being true otherwise. Both transitions are logged; when the data
comes back the UH rejoins. An input never heard at all is stale ``startup_grace`` wall seconds after
the first own state. A controller restarted in a running team (its first own state is not step 0)
skips the transient-local history it receives until its own state is the newest step it knows of,
so it joins at the current step instead of replaying the last ``STEP_DEPTH`` steps.
"""
from __future__ import annotations

import numpy as np

import uh_runtime as rt
from uh_controller_node.control_kernels import compile_control_kernels
from uh_controller_node.controller import ControllerError, UHController
from uh_controller_node.gains import CASES, ControllerGains, GainsError, gain_parameters, nest_gains
from uh_controller_node.impairments import ReceivedStates, compile_impairment_kernels
from uh_controller_node.input_sync import OWN, REFERENCE, InputSynchroniser
from uh_runtime import messages as m
from uh_wire.run_config import RunConfigError, declare_run_parameters, declare_view_parameters
from uh_wire.wire import (WireError, command_to_msg, msg_to_reference, msg_to_state, received_states_to_msg,
                          status_to_msg)
from uh_core import diagnostics
from uh_wire import topics
from uh_wire.standard_msgs import diagnostic_array_msg, view_publisher

__all__ = ['ControllerNode', 'main']

#: Period of the realtime check for a silent own state and the start-up grace, wall s.
SLOW_POLL_S = 0.1

#: Floating-point parameters of the synchroniser: (name, default, upper bound, description).
SYNC_PARAMETERS = (
    ('sync_wait', 0.004, 1.0,
     'realtime: wall seconds to wait for same-step neighbour data before using the latest'),
    ('stale_timeout', 0.25, 60.0,
     'realtime: simulated seconds a neighbour\'s state (or the reference) may lag the own '
     'state before it is reported stale and left out of the control law'),
    ('startup_grace', 1.0, 600.0,
     'realtime: wall seconds after the first own state before an input never heard is stale'),
)


class ControllerNode(rt.Node):
    """Controller of UH ``uh_id`` (parameter); see the module docstring for the behaviour."""

    def __init__(self, **kwargs):
        super().__init__('controller', **kwargs)
        run = declare_run_parameters(self)
        self.declare_parameter('case', 'proposed', rt.ParameterDescriptor(
            description='controller variant: proposed, case1 (beta = 1), case2 (no serial-parallel '
                        'estimation model)', read_only=True))
        for name, default, upper, text in SYNC_PARAMETERS:
            self.declare_parameter(name, default, rt.ParameterDescriptor(
                description=text, read_only=True,
                floating_point_range=[rt.FloatingPointRange(from_value=0.0, to_value=upper, step=0.0)]))
        sync = {name: float(self.get_parameter(name).value) for name, *_ in SYNC_PARAMETERS}
        case = str(self.get_parameter('case').value)
        if case not in CASES:
            raise RunConfigError(f"parameter 'case' is {case!r}; allowed: {', '.join(CASES)}")
        self.uh_id, self.dt, scenario = run.uh_id, run.dt, run.scenario
        self.case = case
        self.gain_names = self._declare_gains(scenario)
        self.controller = UHController(self.uh_id, scenario, case=case, gains=self._gains_of({}))
        self.add_on_set_parameters_callback(self._check_gains)
        self.add_post_set_parameters_callback(self._apply_gains)
        # load the control law's numba kernel now (before the endpoints exist and the clock can start)
        compile_control_kernels()
        neighbours = tuple(scenario.neighbours(self.uh_id))
        linked = scenario.leader_link(self.uh_id) > 0
        self.received = None
        if scenario.impairments is not None:
            if run.clock_mode != 'lockstep':
                raise RunConfigError(f'scenario {scenario.name!r} has impairments, which are defined on control '
                                     'steps: run it with clock_mode lockstep (--clock lockstep)')
            self.received = ReceivedStates(self.uh_id, neighbours, scenario.impairments, self.dt)
            compile_impairment_kernels()
        self.sync = InputSynchroniser(self.uh_id, neighbours, linked, mode=run.clock_mode, dt=run.dt,
                                      last_step=run.last_step, reachable=self.controller.reachable_without,
                                      logger=self.get_logger(), **sync)
        self.published = {'command': 0, 'status': 0}
        qos = topics.qos_profile(topics.STEP_QOS)
        self.command_pub = self.create_publisher(m.ActuatorCommand, topics.COMMAND.name, qos)
        self.status_pub = self.create_publisher(m.ControllerStatus, topics.STATUS.name, qos)
        if self.received is not None:
            self.received_pub = self.create_publisher(m.ReceivedStates, topics.RECEIVED.name, qos)
            self.published['received'] = 0
        self.views = declare_view_parameters(self, self.dt)
        self.diagnostics_phase = self.views.diagnostics_phase(scenario.ids, self.uh_id, controller=True)
        self.window = diagnostics.ControllerWindow()
        self._rejected_reported = 0
        if self.views.enabled:
            self.diag_pub = view_publisher(self, topics.DIAGNOSTICS)
        self.create_subscription(m.UHState, topics.STATE.name, self.on_own_state, qos)
        for j in neighbours:
            self.create_subscription(m.UHState, topics.uh_topic(j, topics.STATE),
                                     lambda msg, j=j: self.on_neighbour_state(j, msg), qos)
        if linked:
            self.create_subscription(m.Reference, topics.REFERENCE.name, self.on_reference, qos)
        self._deadline = None
        if run.clock_mode == 'realtime':
            # no busy polling: a one-shot timer armed only while a step waits for its neighbours'
            # data (sync_wait after its own state), and a slow one for silence and start-up checks
            self._deadline = self.create_timer(max(sync['sync_wait'], 0.0005), self._on_deadline)
            self._deadline.cancel()
            self.create_timer(SLOW_POLL_S, self._on_deadline)
        self.get_logger().info(f'uh{self.uh_id} ({case}, {run.clock_mode}): hears '
                               f"{', '.join(f'uh{j}' for j in neighbours) or 'no UH'}"
                               f"{' and the virtual leader' if linked else ''}")

    # -- gains as parameters (docs/control_law.md#gains-as-parameters) ---------------------------
    def _declare_gains(self, scenario) -> tuple:
        """Declare every gain of the scenario's gains file as a parameter (``beta``, ``outer.k`` ...):
        the file's value is the default, ``--params-file`` (``/**:``) or ``-p`` override it.
        """
        names = []
        for g in gain_parameters(scenario.gains, source=f'gains of scenario {scenario.name!r}'):
            ranges = {}
            if isinstance(g.value, int):
                ranges['integer_range'] = [rt.IntegerRange(from_value=1, to_value=100000, step=1)]
            elif g.minimum is not None:
                ranges['floating_point_range'] = [rt.FloatingPointRange(from_value=g.minimum, to_value=1e12, step=0.0)]
            self.declare_parameter(g.name, g.value, rt.ParameterDescriptor(
                description=g.description, read_only=g.read_only, **ranges))
            names.append(g.name)
        return tuple(names)

    def _gains_of(self, changes: dict) -> ControllerGains:
        """The controller's gains from the current parameter values with ``changes`` applied
        (validated like the gains file; :class:`GainsError` says what is wrong).
        """
        flat = {name: self.get_parameter(name).value for name in self.gain_names}
        flat.update(changes)
        return ControllerGains.from_mapping(nest_gains(flat), self.case, source=f'uh{self.uh_id} controller gains')

    def _check_gains(self, params):
        """Accept a change of gains only if the gains it makes pass the gains file's checks."""
        changes = {p.name: p.value for p in params if p.name in self.gain_names}
        if changes:
            try:
                self._gains_of(changes)
            except GainsError as exc:
                self.get_logger().warning(f'gain change {changes} rejected: {exc}')
                return rt.SetParametersResult(successful=False, reason=str(exc))
        return rt.SetParametersResult(successful=True)

    def _apply_gains(self, params) -> None:
        changed = [p for p in params if p.name in self.gain_names]
        if changed:
            self.controller.set_gains(self._gains_of({}))
            self.get_logger().info('gains changed: ' + ', '.join(f'{p.name} = {p.value}' for p in changed))

    # -- inputs ------------------------------------------------------------------------------------
    def on_own_state(self, msg) -> None:
        self._offer(OWN, msg, 'own state', msg_to_state, self.uh_id)

    def on_neighbour_state(self, j: int, msg) -> None:
        self._offer(j, msg, f'state of uh{j}', msg_to_state, j)

    def on_reference(self, msg) -> None:
        self._offer(REFERENCE, msg, 'reference', msg_to_reference)

    def _offer(self, key, msg, what: str, convert, *expected_id) -> None:
        try:
            value = convert(msg, *expected_id)
        except WireError as exc:
            self.sync.reject(what, exc)
            return
        self._compute(self.sync.offer(key, int(msg.step), value))
        if key == OWN and self._deadline is not None and self.sync.waiting is not None:
            self._deadline.reset()     # fires once, sync_wait from now, unless the step is released first

    def _on_deadline(self) -> None:
        """realtime: the step waited for is due (or the slow check): release it with the latest data."""
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
            try:
                if inputs.stale:
                    u, status = self.controller.step_degraded(k, own, neighbours, inputs.reference,
                                                              self.dt, hold=inputs.hold)
                else:
                    u, status = self.controller.step(k, own, neighbours, inputs.reference, self.dt)
            except ControllerError as exc:  # inputs the law cannot use: no command this step, the node lives on
                self.get_logger().error(f'step {k} not computed: {exc}', throttle_duration_sec=1.0)
                self.window.not_computed += 1
                continue
            t = k * self.dt
            self.command_pub.publish(command_to_msg(self.uh_id, k, t, u))
            self.status_pub.publish(status_to_msg(self.uh_id, k, t, status, inputs.stale_labels))
            self.published['command'] += 1
            self.published['status'] += 1
            if self.received is not None:
                self.received_pub.publish(received_states_to_msg(self.uh_id, k, self.dt, own, neighbours,
                                                                 self.received.sample_steps))
                self.published['received'] += 1
            if self.views.enabled:
                self._diagnose(k, t, inputs, status)

    def _diagnose(self, k: int, t: float, inputs, status) -> None:
        """Add step k to the diagnostics window; publish it every ``views.diagnostics_every`` steps
        (docs/visualization.md#diagnostics). Per step only counters; the rest at the report.
        """
        w = self.window
        w.steps += 1
        if status.saturated_tilt or status.saturated_collective or status.saturated_cyclic:
            w.saturated_steps += 1
        for stats in self.sync.lag.values():
            if stats.last > w.max_input_lag:
                w.max_input_lag = stats.last
        if k % self.views.diagnostics_every != self.diagnostics_phase:
            return
        w.last_step = k
        w.stale_neighbours = tuple(inputs.stale_labels)
        w.holding = inputs.hold is not None
        w.fault_isolated = tuple(status.isolation.isolated)
        w.fault_estimate_position = float(np.linalg.norm(status.fault_estimate_position))
        w.fault_estimate_attitude = float(np.linalg.norm(status.fault_estimate_attitude))
        rejected = sum(self.sync.rejected.values())
        w.rejected_inputs, self._rejected_reported = rejected - self._rejected_reported, rejected
        self.diag_pub.publish(diagnostic_array_msg(t, [diagnostics.controller_diagnostic(self.uh_id, w)]))
        self.window = diagnostics.ControllerWindow()

    def destroy_node(self):
        if hasattr(self, 'published'):  # not when the constructor failed half-way
            rejected = self.sync.rejected_summary()
            rt.log_on_exit(
                self,
                f"published: {topics.uh_topic(self.uh_id, topics.COMMAND)} {self.published['command']}, "
                f"{topics.uh_topic(self.uh_id, topics.STATUS)} {self.published['status']}"
                + (f'; rejected inputs: {rejected}' if rejected else ''))
            lag = self.sync.lag_summary()
            if lag:
                rt.log_on_exit(self, lag)
        return super().destroy_node()


def main(args=None):
    rt.run_node(ControllerNode, args)


if __name__ == '__main__':
    main()
