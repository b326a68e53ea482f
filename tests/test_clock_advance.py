"""The clock node's step advancement without ROS (uh_sim_node.clock_advance).

Lockstep waits for every UH's command and for the recorder, realtime starts ticking once the team is live and ticks
every dt / rate wall seconds.

Deterministic: wall time comes from a fake clock, log lines go to a list; no sleeps, no DDS.
"""
import pytest
from fake_wall import FakeClock, RecordingLogger

from uh_sim_node.clock_advance import REALTIME_FINAL_WAIT_S, ClockAdvancer

IDS = (1, 2, 3)
DT = 0.01


def make(mode='lockstep', last_step=20, **kwargs):
    clock, logger = FakeClock(), RecordingLogger()
    advancer = ClockAdvancer(IDS, mode=mode, dt=DT, last_step=last_step, logger=logger, now=clock, **kwargs)
    return advancer, clock, logger


def command_all(advancer, k, ids=IDS):
    out = []
    for i in ids:
        out += advancer.on_command(i, k)
    return out


# -- lockstep -----------------------------------------------------------------------------------------
def test_lockstep_advances_only_when_every_uh_commanded_the_step():
    advancer, _, _ = make()
    assert advancer.on_command(1, 0) == []          # nothing before step 0 is out
    assert advancer.start() == [0]
    assert advancer.on_command(2, 0) == []
    assert advancer.on_command(2, 0) == []          # a duplicate does not count twice
    assert advancer.on_command(3, 0) == [1]
    assert advancer.step == 1
    assert command_all(advancer, 0) == []           # a late copy of an old step changes nothing
    assert command_all(advancer, 1, ids=(1, 2)) == []


def test_lockstep_commands_that_arrive_early_are_kept():
    advancer, _, _ = make()
    advancer.start()
    assert command_all(advancer, 1) == []           # step 1 complete while step 0 is not
    assert command_all(advancer, 0, ids=(1, 2)) == []
    assert advancer.on_command(3, 0) == [1, 2]      # both steps go out, in order


def test_lockstep_waits_for_the_recorder():
    advancer, _, _ = make(expect_recorder=True, recorder_lag_steps=2)
    advancer.start()
    released = []
    for k in range(6):
        released += command_all(advancer, k)
    assert released == [1, 2]                       # step 3 needs the recorder at step 2 - 2 or later
    assert advancer.on_progress(0) == [3]
    assert advancer.on_progress(1) == [4]
    assert advancer.on_progress(3) == [5, 6]        # the commands of steps 4, 5 were already in


def test_lockstep_completes_when_the_recorder_has_the_last_step():
    advancer, clock, logger = make(last_step=3, expect_recorder=True, recorder_lag_steps=40)
    advancer.start()
    for k in range(4):
        command_all(advancer, k)
        clock.advance(0.5)
    assert advancer.step == 3 and not advancer.done
    assert advancer.on_progress(2) == [] and not advancer.done
    assert advancer.on_progress(3) == [] and advancer.done
    assert logger.texts()[-1] == 'run complete: 3 steps, sim 0.03 s in 2.00 s wall (real-time factor 0.01)'
    assert command_all(advancer, 3) == []           # nothing after the end


def test_lockstep_without_a_recorder_completes_with_the_last_commands():
    advancer, _, _ = make(last_step=2)
    advancer.start()
    command_all(advancer, 0)
    command_all(advancer, 1)
    assert not advancer.done
    command_all(advancer, 2)
    assert advancer.done and advancer.step == 2


def test_progress_is_logged_every_tenth_of_the_run():
    advancer, clock, logger = make(last_step=20)
    advancer.start()
    for k in range(20):
        clock.advance(0.005)
        command_all(advancer, k)
    progress = [t for t in logger.texts('info') if t.startswith('step ')]
    assert len(progress) == 10
    assert progress[0] == 'step 2/20: sim 0.02 s, wall 0.01 s, real-time factor 2.00'


# -- realtime -----------------------------------------------------------------------------------------
def test_realtime_starts_ticking_once_every_uh_commanded_step_0():
    advancer, _, logger = make('realtime')
    assert advancer.start_ticking() is False        # not started yet
    assert advancer.start() == [0]
    assert command_all(advancer, 0, ids=(1, 2)) == []
    assert advancer.on_command(3, 1) == []          # only step 0's commands count
    assert advancer.start_ticking() is False
    advancer.on_command(3, 0)
    assert advancer.start_ticking() is True
    assert advancer.start_ticking() is False        # once
    assert advancer.ticking and logger.texts('warning') == []


def test_realtime_ticks_anyway_after_the_start_wait():
    advancer, clock, logger = make('realtime', start_wait=10.0)
    advancer.start()
    command_all(advancer, 0, ids=(1,))
    clock.advance(9.9)
    assert advancer.start_ticking() is False
    clock.advance(0.2)
    assert advancer.start_ticking() is True
    assert logger.texts('warning') == ['no command of step 0 from uh2, uh3 after 10 s: starting the '
                                       'realtime ticks anyway']


@pytest.mark.parametrize('rate', [1.0, 2.0, 0.5])
def test_realtime_tick_schedule_follows_the_rate(rate):
    """The node's timer calls tick() every tick_period = dt / rate wall seconds.

    Each tick releases the next step whatever the commands; the progress lines report the rate as the real-time factor.
    """
    advancer, clock, logger = make('realtime', last_step=10, rate=rate, expect_recorder=True)
    assert advancer.tick_period == pytest.approx(DT / rate)
    advancer.start()
    command_all(advancer, 0)
    clock.advance(0.3)                              # the start-up wait does not count
    assert advancer.start_ticking()
    released = []
    for _ in range(12):
        clock.advance(advancer.tick_period)
        released.append(advancer.tick())
        assert advancer.on_command(1, advancer.step) == []   # commands do not drive the ticks
    assert released == [*range(1, 11), None, None]
    assert [t for t in logger.texts('info') if t.startswith('step 10/')] == [
        f'step 10/10: sim 0.10 s, wall {10 * DT / rate:.2f} s, real-time factor {rate:.2f}']
    assert not advancer.done                         # waits for the recorder to confirm step 10
    assert advancer.on_progress(9) == [] and not advancer.done
    advancer.on_progress(10)
    assert advancer.done
    assert logger.texts('info')[-1].startswith('run complete: 10 steps, sim 0.10 s in ')


def test_realtime_gives_up_waiting_for_the_recorder():
    advancer, _, logger = make('realtime', last_step=2, expect_recorder=True)
    advancer.start()
    command_all(advancer, 0)
    advancer.start_ticking()
    assert [advancer.tick() for _ in range(3)] == [1, 2, None]
    advancer.on_progress(1)
    assert not advancer.done
    advancer.give_up()
    assert advancer.done
    assert logger.texts('warning') == [f'the recorder did not confirm the last step within {REALTIME_FINAL_WAIT_S} s '
                                       '(recorded up to step 1); ending the run']
    advancer.give_up()                               # once
    assert len(logger.texts('warning')) == 1


def test_stop_ends_the_run_and_nothing_advances():
    advancer, _, _ = make()
    advancer.stop()
    assert advancer.done
    advancer.step = 0
    assert command_all(advancer, 0) == []


def test_unknown_mode_is_an_error():
    with pytest.raises(ValueError, match="clock mode 'fast'"):
        make('fast')
