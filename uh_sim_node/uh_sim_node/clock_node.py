"""Clock node (``clock``): publishes ``/clock`` (rosgraph_msgs/Clock), one message per step.

- ``lockstep``: waits until every node of the team is discovered (publishers and subscribers of
  every team topic, see :func:`expected_endpoints`), publishes step 0, and advances to step k+1 only
  when the commands of every UH for step k have arrived and, if a recorder is expected, the
  recorder has written everything up to step k - ``RECORDER_LAG_STEPS`` (so nothing is dropped).
  After the last step K it waits for the recorder to have written step K, then exits: the run is
  deterministic and as fast as the slowest node allows.
- ``realtime``: publishes step 0 and waits until every UH's command of step 0 has arrived (the
  team is live: every controller has heard its inputs and answered; at most
  ``REALTIME_START_WAIT_S``), then a wall-clock timer publishes step k+1 every dt / rate seconds.
  Without that wait the first steps of a team whose processes are still finishing their start-up
  would count as missed.
"""
from __future__ import annotations

import time

import uh_runtime as rt
from uh_runtime import messages as m
from uh_sim_node.run_config import declare_run_parameters
from uh_sim_node.wire import clock_msg, clock_step, stamp_seconds
from uh_topology import topics

__all__ = ['ClockNode', 'expected_endpoints', 'main']

#: realtime: how long after the last tick the clock waits for the recorder to confirm the last step
REALTIME_FINAL_WAIT_S = 5.0
#: realtime: how long the clock waits at step 0 for every UH's first command before ticking anyway
REALTIME_START_WAIT_S = 10.0


def expected_endpoints(scenario, recorder: bool) -> dict[str, tuple[int, int]]:
    """Minimum (publishers, subscribers) of every team topic once all nodes of a run are up."""
    rec = 1 if recorder else 0
    hears = {j: [i for i in scenario.ids if j in scenario.neighbours(i)] for j in scenario.ids}
    linked = [i for i in scenario.ids if scenario.leader_link(i) > 0]
    out = {topics.CLOCK.name: (1, len(scenario.ids) + 1 + rec),     # sims, virtual leader
           topics.REFERENCE.name: (1, len(linked) + rec)}
    for i in scenario.ids:
        out[topics.uh_topic(i, topics.STATE)] = (1, 1 + len(hears[i]) + rec)
        out[topics.uh_topic(i, topics.COMMAND)] = (1, 2 + rec)         # sim, clock
        out[topics.uh_topic(i, topics.STATUS)] = (1, rec)
        out[topics.uh_topic(i, topics.FAULT_TRUTH)] = (1, rec)
    return out


class ClockNode(rt.Node):
    def __init__(self, **kwargs):
        super().__init__('clock', **kwargs)
        run = declare_run_parameters(self, per_uh=False)
        self.declare_parameter('rate', 1.0, rt.ParameterDescriptor(
            description='realtime mode: simulated seconds per wall second', read_only=True,
            floating_point_range=[rt.FloatingPointRange(from_value=0.01, to_value=1000.0, step=0.0)]))
        self.declare_parameter('expect_recorder', False, rt.ParameterDescriptor(
            description='lockstep: wait for the recorder (discovery, progress) so no message is lost',
            read_only=True))
        self.declare_parameter('startup_timeout', 60.0, rt.ParameterDescriptor(
            description='s to wait for every node of the team to be discovered', read_only=True,
            floating_point_range=[rt.FloatingPointRange(from_value=1.0, to_value=3600.0, step=0.0)]))
        self.scenario, self.mode = run.scenario, run.clock_mode
        self.dt, self.last_step = run.dt, run.last_step
        self.rate = float(self.get_parameter('rate').value)
        self.expect_recorder = bool(self.get_parameter('expect_recorder').value)
        self.startup_deadline = time.monotonic() + float(self.get_parameter('startup_timeout').value)
        self.expected = expected_endpoints(self.scenario, self.expect_recorder)
        self.step = -1
        self.commands: dict[int, set[int]] = {}
        self.recorded_step = -1
        self.done = False
        self.failed = None
        self.started_wall = None
        self.tick_timer = None
        qos = topics.qos_profile(topics.STEP_QOS)
        self.pub = self.create_publisher(m.Clock, topics.CLOCK.name, qos)
        for i in self.scenario.ids:
            self.create_subscription(m.ActuatorCommand, topics.uh_topic(i, topics.COMMAND),
                                     self.on_command, qos)
        self.create_subscription(m.Time, topics.RECORDER_PROGRESS.name, self.on_progress,
                                 topics.qos_profile(topics.RECORDER_PROGRESS.qos))
        self.startup_timer = self.create_timer(0.05, self.check_startup)

    # -- start -------------------------------------------------------------------------------------
    def missing_endpoints(self) -> list[str]:
        missing = []
        for name, (pubs, subs) in self.expected.items():
            have_p, have_s = self.count_publishers(name), self.count_subscribers(name)
            if have_p < pubs or have_s < subs:
                missing.append(f'{name} (publishers {have_p}/{pubs}, subscribers {have_s}/{subs})')
        return missing

    def check_startup(self) -> None:
        missing = self.missing_endpoints()
        if missing:
            if time.monotonic() > self.startup_deadline:
                self.failed = 'team not complete after the startup timeout; missing: ' + '; '.join(missing)
                self.get_logger().error(self.failed)
                self.done = True
                self.startup_timer.cancel()
            return
        self.startup_timer.cancel()
        self.started_wall = time.monotonic()
        self.get_logger().info(f'team complete ({len(self.scenario.ids)} UHs); {self.mode} run of '
                               f'{self.last_step} steps starts')
        self.publish_step(0)
        if self.mode == 'realtime':
            self.live_deadline = time.monotonic() + REALTIME_START_WAIT_S
            self.live_timer = self.create_timer(0.05, self.start_ticking)
            self.start_ticking()

    def start_ticking(self) -> None:
        """realtime: start the wall-clock ticks once every UH commanded step 0 (or the wait is over)."""
        if self.tick_timer is not None or self.done:
            return
        answered = self.commands.get(0, set())
        if len(answered) < len(self.scenario.ids):
            if time.monotonic() < self.live_deadline:
                return
            missing = sorted(set(self.scenario.ids) - answered)
            self.get_logger().warn(f'no command of step 0 from uh{", uh".join(map(str, missing))} after '
                                   f'{REALTIME_START_WAIT_S:g} s: starting the realtime ticks anyway')
        self.live_timer.cancel()
        self.commands.pop(0, None)
        self.started_wall = time.monotonic()   # the real-time factor counts the ticking loop
        self.tick_timer = self.create_timer(self.dt / self.rate, self.on_tick)

    # -- stepping ----------------------------------------------------------------------------------
    def publish_step(self, k: int) -> None:
        self.step = k
        self.pub.publish(clock_msg(k * self.dt))
        if k and k % max(1, self.last_step // 10) == 0:
            wall = time.monotonic() - self.started_wall
            self.get_logger().info(f'step {k}/{self.last_step}: sim {k * self.dt:.2f} s, wall {wall:.2f} s, '
                                   f'real-time factor {k * self.dt / max(wall, 1e-9):.2f}')

    def on_tick(self) -> None:
        if self.step < self.last_step:
            self.publish_step(self.step + 1)
            return
        self.tick_timer.cancel()
        self.finish_when_recorded()
        # realtime has latest-value semantics: do not wait for ever for a last message that was lost
        self.final_timer = self.create_timer(REALTIME_FINAL_WAIT_S, self.give_up_waiting)

    def give_up_waiting(self) -> None:
        self.final_timer.cancel()
        if not self.done:
            self.get_logger().warn(f'the recorder did not confirm the last step within {REALTIME_FINAL_WAIT_S} s '
                                   f'(recorded up to step {self.recorded_step}); ending the run')
            self.finish_when_recorded(force=True)

    def on_command(self, msg) -> None:
        if self.mode == 'lockstep':  # realtime ticks do not wait for commands (but start on step 0's)
            self.commands.setdefault(int(msg.step), set()).add(int(msg.uh_id))
            self.try_advance()
        elif self.tick_timer is None and int(msg.step) == 0:
            self.commands.setdefault(0, set()).add(int(msg.uh_id))
            self.start_ticking()

    def on_progress(self, msg) -> None:
        self.recorded_step = int(round(stamp_seconds(msg) / self.dt))
        if self.mode == 'lockstep':
            self.try_advance()
        elif self.step >= self.last_step:
            self.finish_when_recorded()

    def try_advance(self) -> None:
        n = len(self.scenario.ids)
        while self.step >= 0 and not self.done and len(self.commands.get(self.step, ())) == n:
            if self.step == self.last_step:
                self.finish_when_recorded()
                return
            if self.expect_recorder and self.recorded_step < self.step - topics.RECORDER_LAG_STEPS:
                return  # the recorder is behind; on_progress retries
            self.commands.pop(self.step, None)
            self.publish_step(self.step + 1)

    def destroy_node(self):
        if hasattr(self, 'step'):  # not when the constructor failed half-way
            self.get_logger().info(f'published: {topics.CLOCK.name} {self.step + 1}')
        return super().destroy_node()

    def finish_when_recorded(self, force: bool = False) -> None:
        if self.done or (self.expect_recorder and self.recorded_step < self.last_step and not force):
            return
        wall = time.monotonic() - self.started_wall
        self.get_logger().info(f'run complete: {self.last_step} steps, sim {self.last_step * self.dt:.2f} s '
                               f'in {wall:.2f} s wall (real-time factor {self.last_step * self.dt / wall:.2f})')
        self.done = True


def main(args=None):
    rt.run_node(ClockNode, args, until=lambda node: node.done,
                exit_code=lambda node: 1 if node.failed else 0)


if __name__ == '__main__':
    main()
