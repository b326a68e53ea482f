"""The report's communication-delay section of one run: the team's delay margin and the ages measured.

Shown for a run whose scenario delays its links or whose controllers used neighbour states older
than a step (a realtime run over a real network). The margin is that of the compensation the
controllers applied (docs/delay.md#delay-margin; the scenario's ``delay_compensation``, or ``none``
in a realtime run without impairments, as :class:`~uh_controller_node.delay_margin.MarginWatch`
checks); the ages are the mean and the largest, over the run, of what each controller's status
reported (docs/topics.md#neighbour-ages).
"""
from __future__ import annotations

import math

from uh_controller_node.delay_margin import applied_compensation, margin_steps_for, scenario_link_age

__all__ = ['DELAY_HEAD', 'delay_section']

DELAY_HEAD = ('UH', 'mean age (ms)', 'largest age (ms)', 'within the margin')


def delay_section(run) -> tuple[str, list] | None:
    """Give ``(sentence, rows of DELAY_HEAD)`` for ``run``, or None when its links are not delayed and nothing aged."""
    scenario, dt = run.scenario, run.scenario.dt
    ages = run.arrays.get('neighbour_ages') or {}
    link_age = scenario_link_age(scenario)
    oldest = max((worst for _, worst in ages.values()), default=0.0)
    if link_age == 0 and oldest <= dt + 1e-9:
        return None
    compensation = applied_compensation(scenario, realtime=run.clock == 'realtime')
    most = max(link_age, int(math.ceil(oldest / dt - 1e-9))) + 1
    steps = margin_steps_for(scenario, run.case, compensation, most)
    margin = f'{steps} steps ({steps * dt * 1000:g} ms)' if steps is not None else f'at least {most} steps'
    sentence = (f'Delay margin of the team ({compensation}; uh-analyze, docs/delay.md#delay-margin): {margin}. '
                f'The scenario\'s links deliver states up to {link_age} steps ({link_age * dt * 1000:g} ms) old.')
    limit = math.inf if steps is None else steps * dt + 1e-9
    rows = [[f'uh{uh}', f'{mean * 1000:.1f}', f'{worst * 1000:.1f}', 'yes' if worst <= limit else 'NO']
            for uh, (mean, worst) in sorted(ages.items())]
    return sentence, rows
