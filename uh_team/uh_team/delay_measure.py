"""The measured onset of a team's delay oscillation, to check the delay margin against (docs/delay.md#delay-margin).

Flies the team in process with the same delay on every link and tells whether it still oscillates
at the end of the run; :mod:`uh_controller_node.delay_margin` predicts where that starts.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from uh_topology.impairments import uniform_impairments

from .team_simulation import run_team_simulation

__all__ = ['OSCILLATION_RATE', 'measured_oscillation', 'measured_onset']


#: A run oscillates when the largest standard deviation of a UH's roll or pitch rate over its last
#: 20 s exceeds this (rad/s). Settled runs of the paper team show about 0.001 rad/s; the ring's
#: oscillation 2-3 rad/s; a mode that still decays, 0.02 (docs/delay.md#delay-margin).
OSCILLATION_RATE = 0.05


def measured_oscillation(scenario, case: str, delay: int, compensation: str, duration: float = 60.0) -> float:
    """Fly ``scenario`` in process with ``delay`` steps on every link, the safety filter off; give the rate spread.

    The largest standard deviation (rad/s) over UHs and the roll and pitch rates over the run's last
    20 s: compare with :data:`OSCILLATION_RATE`. The scenario's own impairments are replaced.
    """
    delayed = dataclasses.replace(scenario, impairments=uniform_impairments(scenario.adjacency, delay, compensation),
                                  safety=dataclasses.replace(scenario.safety, enabled=False))
    run = run_team_simulation(delayed, case, duration=duration)
    last = run.states[-int(round(20.0 / scenario.dt)):, :, 9:11]
    return float(np.nanmax(np.nanstd(last, axis=0)))


def measured_onset(scenario, case: str, compensation: str, delays) -> int | None:
    """Give the first delay of ``delays`` (ascending) whose run oscillates (:func:`measured_oscillation`), or None."""
    for delay in delays:
        if measured_oscillation(scenario, case, delay, compensation) > OSCILLATION_RATE:
            return delay
    return None
