"""Controller node of one helicopter: ``controller`` in namespace ``/uhN``.

It subscribes to its own ``state``, to ``/uhj/state`` of exactly the UHs j with a_ij != 0 (its
neighbours in the scenario's graph, :mod:`uh_topology`), and to ``/reference`` only if a_i0 != 0,
runs :class:`uh_controller_node.controller.UHController` and publishes ``command`` and ``status``.

- ``lockstep``: step k is computed once the own state k, every neighbour's state k and (if linked)
  reference k have arrived, in step order, so the run reproduces the in-process reference
  simulation exactly.
- ``realtime``: each own state k starts step k. It is computed as soon as every neighbour's state
  and the reference of the same step are in, or after ``sync_wait`` wall seconds with the latest
  values received (latest-value semantics). The short wait matters: the sims publish step k at the
  same tick, and mixing step-k and step-(k-1) neighbour data makes the consensus error jitter by
  v dt, which the command filters' derivatives amplify into chattering commands.

Received messages carrying NaN/inf are rejected (logged); the last valid input is kept.
"""
from __future__ import annotations

import time

import uh_runtime as rt
from uh_controller_node.controller import UHController
from uh_runtime import messages as m
from uh_sim_node.run_config import declare_run_parameters
from uh_sim_node.wire import WireError, command_to_msg, msg_to_reference, msg_to_state, status_to_msg
from uh_topology import topics

__all__ = ['ControllerNode', 'main', 'CASES']

CASES = ('proposed', 'case1', 'case2')


class ControllerNode(rt.Node):
    def __init__(self, **kwargs):
        super().__init__('controller', **kwargs)
        run = declare_run_parameters(self)
        self.declare_parameter('case', 'proposed', rt.ParameterDescriptor(
            description='controller variant: proposed, case1 (beta = 1), case2 (no serial-parallel '
                        'estimation model)', read_only=True))
        self.declare_parameter('sync_wait', 0.004, rt.ParameterDescriptor(
            description='realtime: wall seconds to wait for same-step neighbour data before using the latest',
            read_only=True, floating_point_range=[rt.FloatingPointRange(from_value=0.0, to_value=1.0, step=0.0)]))
        self.sync_wait = float(self.get_parameter('sync_wait').value)
        case = str(self.get_parameter('case').value)
        if case not in CASES:
            from uh_sim_node.run_config import RunConfigError
            raise RunConfigError(f"parameter 'case' is {case!r}; allowed: {', '.join(CASES)}")
        self.uh_id, self.mode, self.dt, self.last_step = run.uh_id, run.clock_mode, run.dt, run.last_step
        scenario = run.scenario
        self.controller = UHController(self.uh_id, scenario, case=case)
        self.neighbours = tuple(scenario.neighbours(self.uh_id))
        self.linked = scenario.leader_link(self.uh_id) > 0
        self.pending: dict[int, dict] = {}   # lockstep: step -> {'own': x, j: x_j, 'ref': r}
        self.latest: dict = {}               # realtime: key -> (step, latest valid input)
        self.waiting = None                  # realtime: (step, wall deadline) of the step being assembled
        self.next_step = 0
        qos = topics.qos_profile(topics.STEP_QOS)
        self.command_pub = self.create_publisher(m.ActuatorCommand, topics.COMMAND.name, qos)
        self.status_pub = self.create_publisher(m.ControllerStatus, topics.STATUS.name, qos)
        self.create_subscription(m.UHState, topics.STATE.name, self.on_own_state, qos)
        for j in self.neighbours:
            self.create_subscription(m.UHState, topics.uh_topic(j, topics.STATE),
                                     lambda msg, j=j: self.on_neighbour_state(j, msg), qos)
        if self.linked:
            self.create_subscription(m.Reference, topics.REFERENCE.name, self.on_reference, qos)
        if self.mode == 'realtime':
            self.create_timer(max(self.sync_wait / 2, 0.0005), self._run_realtime)
        self.get_logger().info(f'uh{self.uh_id} ({case}, {self.mode}): hears '
                               f"{', '.join(f'uh{j}' for j in self.neighbours) or 'no UH'}"
                               f"{' and the virtual leader' if self.linked else ''}")

    # -- inputs ------------------------------------------------------------------------------------
    def _accept(self, key, k: int, value) -> None:
        if self.mode == 'lockstep':
            if k >= self.next_step:
                self.pending.setdefault(k, {})[key] = value
            self._run_ready_steps()
        else:
            self.latest[key] = (k, value)
            if key == 'own':
                self.waiting = (k, time.monotonic() + self.sync_wait)
            self._run_realtime()

    def on_own_state(self, msg) -> None:
        try:
            self._accept('own', int(msg.step), msg_to_state(msg, expected_id=self.uh_id))
        except WireError as exc:
            self.get_logger().error(f'rejected own state: {exc}; keeping the last valid one')

    def on_neighbour_state(self, j: int, msg) -> None:
        try:
            self._accept(j, int(msg.step), msg_to_state(msg, expected_id=j))
        except WireError as exc:
            self.get_logger().error(f'rejected state of uh{j}: {exc}; keeping the last valid one')

    def on_reference(self, msg) -> None:
        try:
            self._accept('ref', int(msg.step), msg_to_reference(msg))
        except WireError as exc:
            self.get_logger().error(f'rejected reference: {exc}; keeping the last valid one')

    # -- stepping ----------------------------------------------------------------------------------
    def _complete(self, inputs: dict) -> bool:
        return 'own' in inputs and all(j in inputs for j in self.neighbours) and (not self.linked or 'ref' in inputs)

    def _run_ready_steps(self) -> None:
        while self.next_step <= self.last_step and self._complete(self.pending.get(self.next_step, {})):
            inputs = self.pending.pop(self.next_step)
            self._compute(self.next_step, inputs)
            self.next_step += 1

    def _run_realtime(self) -> None:
        if self.waiting is None:
            return
        k, deadline = self.waiting
        keys = (*self.neighbours, *(('ref',) if self.linked else ()))
        if not all(key in self.latest for key in keys):
            return  # waits for the first message of every neighbour
        if k > self.last_step:
            self.waiting = None
            return
        if all(self.latest[key][0] >= k for key in keys) or time.monotonic() >= deadline:
            self.waiting = None
            self._compute(k, {key: value for key, (_, value) in self.latest.items()})

    def _compute(self, k: int, inputs: dict) -> None:
        neighbour_states = {j: inputs[j] for j in self.neighbours}
        u, status = self.controller.step(k, inputs['own'], neighbour_states, inputs.get('ref'), self.dt)
        t = k * self.dt
        self.command_pub.publish(command_to_msg(self.uh_id, k, t, u))
        self.status_pub.publish(status_to_msg(self.uh_id, k, t, status))


def main(args=None):
    rt.run_node(ControllerNode, args)


if __name__ == '__main__':
    main()
