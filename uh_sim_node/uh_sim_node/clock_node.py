"""Clock node (``clock``): publishes ``/clock`` (rosgraph_msgs/Clock), one message per step.

- ``lockstep``: waits until every node of the team is discovered (publishers and subscribers of
  every team topic, see :func:`expected_endpoints`) and, if a recorder is expected, until the
  recorder has subscribed to every topic the run publishes (:func:`uh_wire.topics.run_topics`:
  the views and ``/markers`` included, so no topic's first samples are published before the
  recorder's reader exists), publishes step 0, and advances to step k+1 only
  when the commands of every UH for step k have arrived and, if a recorder is expected, the
  recorder has written everything up to step k - ``RECORDER_LAG_STEPS`` (so nothing is dropped).
  After the last step K it waits for the recorder to have written step K, then exits: the run is
  deterministic and as fast as the slowest node allows.
- ``realtime``: publishes step 0 and waits until every UH's command of step 0 has arrived (the
  team is live: every controller has heard its inputs and answered; at most
  ``REALTIME_START_WAIT_S``), then a wall-clock timer publishes step k+1 every dt / rate seconds.
  Without that wait the first steps of a team whose processes are still finishing their start-up
  would count as missed.

The node discovers the team and publishes; which step comes next, and when, is decided by
:class:`uh_sim_node.clock_advance.ClockAdvancer` (no ROS, injectable wall clock).
"""
from __future__ import annotations

import time

import uh_runtime as rt
from uh_runtime import messages as m
from uh_sim_node.clock_advance import REALTIME_FINAL_WAIT_S, REALTIME_START_WAIT_S, ClockAdvancer
from uh_wire import topics
from uh_wire.run_config import declare_run_parameters, declare_standard_views
from uh_wire.run_defaults import DEFAULT_STARTUP_TIMEOUT
from uh_wire.wire import clock_msg, stamp_seconds

__all__ = ['ClockNode', 'expected_endpoints', 'RECORDER_NODE', 'main', 'REALTIME_FINAL_WAIT_S', 'REALTIME_START_WAIT_S']


def expected_endpoints(scenario, recorder: bool) -> dict[str, tuple[int, int]]:
    """Minimum (publishers, subscribers) of every team topic once all nodes of a run are up."""
    rec = 1 if recorder else 0
    hears = {j: [i for i in scenario.ids if j in scenario.neighbours(i)] for j in scenario.ids}
    linked = [i for i in scenario.ids if scenario.leader_link(i) > 0]
    out = {topics.CLOCK.name: (1, len(scenario.ids) + 1 + rec),     # sims, virtual leader
           topics.REFERENCE.name: (1, len(linked) + rec)}
    sensing = 1 if scenario.safety.enabled else 0   # the sensing node hears every state, serves each proximity
    for i in scenario.ids:
        out[topics.uh_topic(i, topics.STATE)] = (1, 1 + len(hears[i]) + sensing + rec)
        if sensing:
            out[topics.uh_topic(i, topics.PROXIMITY)] = (1, 1 + rec)
        out[topics.uh_topic(i, topics.COMMAND)] = (1, 2 + rec)         # sim, clock
        out[topics.uh_topic(i, topics.STATUS)] = (1, rec)
        out[topics.uh_topic(i, topics.FAULT_TRUTH)] = (1, rec)
    return out


#: Name of the run's recorder node (uh_bringup.team_nodes), whose subscriptions the clock waits for.
RECORDER_NODE = 'recorder'


class ClockNode(rt.Node):
    """The run's clock; see the module docstring for the behaviour.

    Parameters (ROS): the run parameters, ``rate``, ``expect_recorder``, ``startup_timeout`` and
    ``expect_visualization``. Keyword arguments go to ``Node`` (e.g. ``cli_args``).
    """

    def __init__(self, **kwargs):
        super().__init__('clock', **kwargs)
        run = declare_run_parameters(self, per_uh=False)
        self.declare_parameter('rate', 1.0, rt.ParameterDescriptor(
            description='realtime mode: simulated seconds per wall second', read_only=True,
            floating_point_range=[rt.FloatingPointRange(from_value=0.01, to_value=1000.0, step=0.0)]))
        self.declare_parameter('expect_recorder', False, rt.ParameterDescriptor(
            description='lockstep: wait for the recorder (discovery, progress) so no message is lost',
            read_only=True))
        self.declare_parameter('startup_timeout', DEFAULT_STARTUP_TIMEOUT, rt.ParameterDescriptor(
            description='s to wait for every node of the team to be discovered', read_only=True,
            floating_point_range=[rt.FloatingPointRange(from_value=1.0, to_value=3600.0, step=0.0)]))
        self.scenario, self.mode, self.dt = run.scenario, run.clock_mode, run.dt
        expect_recorder = bool(self.get_parameter('expect_recorder').value)
        self.startup_deadline = time.monotonic() + float(self.get_parameter('startup_timeout').value)
        self.expected = expected_endpoints(self.scenario, expect_recorder)
        self.clock = ClockAdvancer(self.scenario.ids, mode=self.mode, dt=run.dt, last_step=run.last_step,
                                   rate=float(self.get_parameter('rate').value), expect_recorder=expect_recorder,
                                   logger=self.get_logger())
        self.failed = None
        self.tick_timer = None
        qos = topics.qos_profile(topics.STEP_QOS)
        self.pub = self.create_publisher(m.Clock, topics.CLOCK.name, qos)
        for i in self.scenario.ids:
            self.create_subscription(m.ActuatorCommand, topics.uh_topic(i, topics.COMMAND),
                                     lambda msg, i=i: self.on_command(i, msg), qos)
        self.create_subscription(m.Time, topics.RECORDER_PROGRESS.name, self.on_progress,
                                 topics.qos_profile(topics.RECORDER_PROGRESS.qos))
        self.declare_parameter('expect_visualization', False, rt.ParameterDescriptor(
            description='the run has a visualisation node: with expect_recorder, wait for the recorder on /markers',
            read_only=True))
        views = declare_standard_views(self)
        flags = topics.scenario_flags(self.scenario)
        self.recorded = ([name for name, _ in topics.run_topics(
            self.scenario.ids, flags['impaired'], views, bool(self.get_parameter('expect_visualization').value),
            flags['safety'])] if expect_recorder else [])
        self.startup_timer = self.create_timer(0.05, self.check_startup)

    @property
    def done(self) -> bool:
        """The run is complete, or the team never came up (``failed``)."""
        return self.clock.done

    # -- start -------------------------------------------------------------------------------------
    def missing_endpoints(self) -> list[str]:
        """Return what the team still lacks, one line per topic (empty: the team is complete).

        A topic of :func:`expected_endpoints` with fewer publishers or subscribers than expected, then
        (once there is none) a topic to record that the recorder has not subscribed to.
        """
        missing = []
        for name, (pubs, subs) in self.expected.items():
            have_p, have_s = self.count_publishers(name), self.count_subscribers(name)
            if have_p < pubs or have_s < subs:
                missing.append(f'{name} (publishers {have_p}/{pubs}, subscribers {have_s}/{subs})')
        if not missing:   # the team is up: has the recorder subscribed to all it must record?
            missing = [f'{name} (not subscribed by the {RECORDER_NODE})' for name in self.recorded
                       if not any(info.node_name == RECORDER_NODE and info.node_namespace == '/'
                                  for info in self.get_subscriptions_info_by_topic(name))]
        return missing

    def check_startup(self) -> None:
        """Start-up timer: publish step 0 once the team is complete (then realtime ticks), else fail at the timeout."""
        missing = self.missing_endpoints()
        if missing:
            if time.monotonic() > self.startup_deadline:
                self.failed = 'team not complete after the startup timeout; missing: ' + '; '.join(missing)
                self.get_logger().error(self.failed)
                self.clock.stop()
                self.startup_timer.cancel()
            return
        self.startup_timer.cancel()
        self.get_logger().info(f'team complete ({len(self.scenario.ids)} UHs); {self.mode} run of '
                               f'{self.clock.last_step} steps starts')
        self.publish(self.clock.start())
        if self.mode == 'realtime':
            self.live_timer = self.create_timer(0.05, self.start_ticking)
            self.start_ticking()

    def start_ticking(self) -> None:
        """realtime: start the wall-clock ticks once every UH commanded step 0 (or the wait is over)."""
        if self.tick_timer is None and self.clock.start_ticking():
            self.live_timer.cancel()
            self.tick_timer = self.create_timer(self.clock.tick_period, self.on_tick)

    # -- stepping ----------------------------------------------------------------------------------
    def publish(self, steps) -> None:
        """Publish ``/clock`` for each step of ``steps`` (t = k dt simulated seconds), in order."""
        for k in steps:
            self.pub.publish(clock_msg(k * self.dt))

    def on_tick(self) -> None:
        """Publish the next step (realtime timer); after the last, wait ``REALTIME_FINAL_WAIT_S`` s for the recorder."""
        k = self.clock.tick()
        if k is not None:
            self.publish((k,))
            return
        self.tick_timer.cancel()
        # realtime has latest-value semantics: do not wait for ever for a last message that was lost
        self.final_timer = self.create_timer(REALTIME_FINAL_WAIT_S, self.give_up_waiting)

    def give_up_waiting(self) -> None:
        """realtime: the recorder did not confirm the last step in time; end the run."""
        self.final_timer.cancel()
        self.clock.give_up(REALTIME_FINAL_WAIT_S)

    def on_command(self, uh_id: int, msg) -> None:
        """Note UH ``uh_id``'s command of ``msg.step`` (another UH's id: ignored); publish the steps it releases."""
        if int(msg.uh_id) != uh_id:   # counted by the topic it came on, never as another UH's command
            self.get_logger().warning(f'ignored a command carrying uh_id {msg.uh_id} on the command topic '
                                      f'of uh{uh_id}', once=True)
            return
        self.publish(self.clock.on_command(uh_id, int(msg.step)))
        if self.mode == 'realtime':
            self.start_ticking()

    def on_progress(self, msg) -> None:
        """Note the sim time the recorder has written (``/recorder/progress``); publish the steps it releases."""
        self.publish(self.clock.on_progress(int(round(stamp_seconds(msg) / self.dt))))

    def destroy_node(self):
        """Log how many ``/clock`` messages were published; destroy the node."""
        if hasattr(self, 'clock'):  # not when the constructor failed half-way
            rt.log_on_exit(self, f'published: {topics.CLOCK.name} {self.clock.step + 1}')
        return super().destroy_node()


def main(args=None):
    """Console script ``lockstep_clock_node``: run :class:`ClockNode` until done; status 1 if the team never came up."""
    rt.run_node(ClockNode, args, until=lambda node: node.done,
                exit_code=lambda node: 1 if node.failed else 0)


if __name__ == '__main__':
    main()
