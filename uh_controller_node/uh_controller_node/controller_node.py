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

Received messages carrying NaN/inf (or another UH's id) are rejected: the node logs the reason
(at most once a second per input, with a count) and keeps its last valid input, which then ages
like a silent neighbour.

Stale data (realtime only; lockstep waits for every input by construction): a neighbour's state or
the reference whose newest valid step is more than ``stale_timeout`` simulated seconds behind the
step being computed is *stale*. It is listed in ``ControllerStatus.stale_neighbours`` (``uhJ`` or
``reference``) and left out of the control law (:meth:`UHController.step_degraded`): the UH keeps
following the remaining neighbours while the remaining graph still gives it a path from the virtual
leader (Assumption 1, :meth:`UHController.reachable_without`), and holds the position and yaw it had
when that stopped being true otherwise. Both transitions are logged; when the data comes back the
UH rejoins. An input never heard at all is stale ``startup_grace`` wall seconds after the first own
state. A controller restarted in a running team (its first own state is not step 0) skips the
transient-local history it receives until its own state is the newest step it knows of, so it joins
at the current step instead of replaying the last ``STEP_DEPTH`` steps.
"""
from __future__ import annotations

import time

import uh_runtime as rt
from uh_controller_node.control_kernels import compile_control_kernels
from uh_controller_node.controller import ControllerError, UHController
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
        self.declare_parameter('stale_timeout', 0.25, rt.ParameterDescriptor(
            description='realtime: simulated seconds a neighbour\'s state (or the reference) may lag the own '
                        'state before it is reported stale and left out of the control law',
            read_only=True, floating_point_range=[rt.FloatingPointRange(from_value=0.0, to_value=60.0, step=0.0)]))
        self.declare_parameter('startup_grace', 1.0, rt.ParameterDescriptor(
            description='realtime: wall seconds after the first own state before an input never heard is stale',
            read_only=True, floating_point_range=[rt.FloatingPointRange(from_value=0.0, to_value=600.0, step=0.0)]))
        self.sync_wait = float(self.get_parameter('sync_wait').value)
        self.startup_grace = float(self.get_parameter('startup_grace').value)
        case = str(self.get_parameter('case').value)
        if case not in CASES:
            from uh_sim_node.run_config import RunConfigError
            raise RunConfigError(f"parameter 'case' is {case!r}; allowed: {', '.join(CASES)}")
        self.uh_id, self.mode, self.dt, self.last_step = run.uh_id, run.clock_mode, run.dt, run.last_step
        scenario = run.scenario
        self.controller = UHController(self.uh_id, scenario, case=case)
        # load the control law's numba kernel now (before the endpoints exist and the clock can start)
        compile_control_kernels()
        self.neighbours = tuple(scenario.neighbours(self.uh_id))
        self.linked = scenario.leader_link(self.uh_id) > 0
        self.pending: dict[int, dict] = {}   # lockstep: step -> {'own': x, j: x_j, 'ref': r}
        self.latest: dict = {}               # realtime: key -> (step, latest valid input)
        self.waiting = None                  # realtime: (step, wall deadline) of the step being assembled
        self.next_step = 0
        self.stale_steps = max(1, int(round(float(self.get_parameter('stale_timeout').value) / self.dt)))
        self.input_keys = (*self.neighbours, *(('ref',) if self.linked else ()))
        self.newest_step = -1                # realtime: newest step of any valid input
        self.joined = False                  # realtime: a step has been computed
        self.first_own_wall = None           # realtime: wall time of the first own state
        self.last_own_wall = None
        self.own_silent_reported = False
        self.stale: tuple = ()               # realtime: inputs currently stale (keys)
        self.hold = None                     # realtime: (position, yaw) held while the graph breaks Assumption 1
        self.rejected: dict = {}             # input name -> messages rejected
        self.lag: dict = {}                  # realtime: key -> [sum, count, max] of steps behind the own state
        self.published = {'command': 0, 'status': 0}
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
            return
        held = self.latest.get(key)
        if held is not None and k < held[0]:
            return  # older than what is held (reordered, or history replayed after a restart)
        self.latest[key] = (k, value)
        self.newest_step = max(self.newest_step, k)
        if key == 'own':
            now = time.monotonic()
            self.last_own_wall = now
            if self.first_own_wall is None:
                self.first_own_wall = now
                if k > 0:
                    self.get_logger().info(f'joining a running team at step {k} or later')
            if self.own_silent_reported:
                self.own_silent_reported = False
                self.get_logger().info(f'own state arrives again (step {k})')
            if not self.joined and k < self.newest_step - 1:
                return  # history of a running team: wait for the current step
            self.waiting = (k, now + self.sync_wait)
        self._run_realtime(from_timer=False)

    def _reject(self, what: str, exc: Exception) -> None:
        count = self.rejected[what] = self.rejected.get(what, 0) + 1
        self.get_logger().error(f'rejected {what}: {exc}; keeping the last valid one ({count} rejected so far)',
                                throttle_duration_sec=1.0)

    def on_own_state(self, msg) -> None:
        try:
            self._accept('own', int(msg.step), msg_to_state(msg, expected_id=self.uh_id))
        except WireError as exc:
            self._reject('own state', exc)

    def on_neighbour_state(self, j: int, msg) -> None:
        try:
            self._accept(j, int(msg.step), msg_to_state(msg, expected_id=j))
        except WireError as exc:
            self._reject(f'state of uh{j}', exc)

    def on_reference(self, msg) -> None:
        try:
            self._accept('ref', int(msg.step), msg_to_reference(msg))
        except WireError as exc:
            self._reject('reference', exc)

    # -- stepping ----------------------------------------------------------------------------------
    def _complete(self, inputs: dict) -> bool:
        return 'own' in inputs and all(j in inputs for j in self.neighbours) and (not self.linked or 'ref' in inputs)

    def _run_ready_steps(self) -> None:
        while self.next_step <= self.last_step and self._complete(self.pending.get(self.next_step, {})):
            inputs = self.pending.pop(self.next_step)
            self._compute(self.next_step, inputs)
            self.next_step += 1

    def _run_realtime(self, from_timer: bool = True) -> None:
        now = time.monotonic()
        if self.waiting is None:
            self._check_own_silence(now)
            return
        k, deadline = self.waiting
        if k > self.last_step:
            self.waiting = None
            return
        steps = {key: self.latest[key][0] for key in self.input_keys if key in self.latest}
        unheard = [key for key in self.input_keys if key not in steps]
        if unheard and now - self.first_own_wall < self.startup_grace:
            return  # waits for the first message of every input
        still_stale = [key for key in self.stale if key in unheard or steps[key] < k - self.stale_steps]
        if all(key in still_stale or (key in steps and steps[key] >= k) for key in self.input_keys):
            pass  # every input of step k is in, except those already known to be stale: no waiting for them
        elif not from_timer or now < deadline:
            # Late or stale data is judged by the timer only: it runs after every message already
            # received has been handled, so a backlog (a process that was not scheduled for a
            # while) is taken in before anything is declared stale.
            return
        self.waiting = None
        for key, s in steps.items():
            stats = self.lag.setdefault(key, [0, 0, 0])
            behind = max(0, k - s)
            stats[0] += behind
            stats[1] += 1
            stats[2] = max(stats[2], behind)
        stale = tuple(key for key in self.input_keys if key in unheard or steps[key] < k - self.stale_steps)
        self._update_stale(stale, k)
        self.joined = True
        self._compute(k, {key: value for key, (_, value) in self.latest.items()}, stale)

    def _check_own_silence(self, now: float) -> None:
        """Log once when the own state stops arriving (the UH's simulator is gone or cut off)."""
        if (self.last_own_wall is not None and not self.own_silent_reported
                and now - self.last_own_wall > max(1.0, self.startup_grace)
                and self.latest['own'][0] < self.last_step):
            self.own_silent_reported = True
            self.get_logger().warn(f'no own state for {now - self.last_own_wall:.1f} s (newest step '
                                   f'{self.latest["own"][0]}): is {topics.uh_namespace(self.uh_id)}/sim running? '
                                   'No command is computed until it comes back')

    @staticmethod
    def _label(key) -> str:
        return 'reference' if key == 'ref' else f'uh{key}'

    def _update_stale(self, stale: tuple, k: int) -> None:
        if stale == self.stale:
            return
        gone = [key for key in stale if key not in self.stale]
        back = [key for key in self.stale if key not in stale]
        for key in gone:
            newest = self.latest[key][0] if key in self.latest else None
            self.get_logger().warn(
                f'{self._label(key)} is stale at step {k}: '
                + (f'newest valid step {newest}' if newest is not None else 'never heard')
                + f' (timeout {self.stale_steps} steps = {self.stale_steps * self.dt:g} s)')
        for key in back:
            self.get_logger().info(f'{self._label(key)} is fresh again at step {k}')
        self.stale = stale
        lost = {0 if key == 'ref' else key for key in stale}
        if stale and not self.controller.reachable_without(lost):
            if self.hold is None:
                own = self.latest['own'][1]
                self.hold = (own[0:3].copy(), float(own[8]))
                p = self.hold[0]
                self.get_logger().warn(
                    f'without {" and ".join(map(self._label, stale))}, uh{self.uh_id} has no path from the '
                    f'virtual leader (Assumption 1): holding position ({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) m, '
                    f'yaw {self.hold[1]:.3f} rad')
        elif self.hold is not None:
            self.hold = None
            self.get_logger().info('the graph gives a path from the virtual leader again: following the team')
        elif stale:
            left = [self._label(key) for key in self.input_keys if key not in stale]
            self.get_logger().warn(f'continuing with {", ".join(left)} (the remaining graph satisfies Assumption 1)')

    def _compute(self, k: int, inputs: dict, stale: tuple = ()) -> None:
        try:
            if not stale:
                neighbour_states = {j: inputs[j] for j in self.neighbours}
                u, status = self.controller.step(k, inputs['own'], neighbour_states, inputs.get('ref'), self.dt)
            else:
                neighbour_states = {j: inputs[j] for j in self.neighbours if j not in stale}
                reference = inputs.get('ref') if 'ref' not in stale else None
                u, status = self.controller.step_degraded(k, inputs['own'], neighbour_states, reference, self.dt,
                                                          hold=self.hold)
        except ControllerError as exc:  # inputs the law cannot use: no command this step, the node lives on
            self.get_logger().error(f'step {k} not computed: {exc}', throttle_duration_sec=1.0)
            return
        t = k * self.dt
        self.command_pub.publish(command_to_msg(self.uh_id, k, t, u))
        self.status_pub.publish(status_to_msg(self.uh_id, k, t, status, [self._label(key) for key in stale]))
        self.published['command'] += 1
        self.published['status'] += 1

    def destroy_node(self):
        if hasattr(self, 'published'):  # not when the constructor failed half-way
            rejected = ', '.join(f'{what} {n}' for what, n in self.rejected.items())
            self.get_logger().info(
                f"published: {topics.uh_topic(self.uh_id, topics.COMMAND)} {self.published['command']}, "
                f"{topics.uh_topic(self.uh_id, topics.STATUS)} {self.published['status']}"
                + (f'; rejected inputs: {rejected}' if rejected else ''))
            if self.lag:
                self.get_logger().info('input lag behind the own state (steps, mean/max): ' + ', '.join(
                    f'{self._label(key)} {total / max(n, 1):.2f}/{worst}' for key, (total, n, worst) in self.lag.items()))
        return super().destroy_node()

def main(args=None):
    rt.run_node(ControllerNode, args)


if __name__ == '__main__':
    main()
