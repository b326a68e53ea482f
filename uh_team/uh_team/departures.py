"""The departures a scenario makes from the paper's graph and gains (docs/delay.md#remedies).

The paper scenario and the comparison cases keep the paper's graph, gains and law; an option
beyond it is a scenario or gains key, and every run records the ones it set (``metrics.json``'s
``departures``, ``run.json``).
"""
from __future__ import annotations

from uh_controller_node.gains import scenario_gains

__all__ = ['scenario_departures']


def scenario_departures(scenario, case: str = 'proposed') -> dict:
    """Give the departures from the paper's graph and gains that the delay remedies make (docs/delay.md#remedies).

    Any of ``{'reference_links': 'all_leaders'}``, ``{'delay_compensation': 'reference_motion'}``,
    ``{'feedforward_weight': w}`` (w < 1) and, for a scenario with ``events``, ``{'on_loss': 'reform'}``
    (the team re-forms after a loss, docs/resilience.md; ``hold`` is what the law does without this
    layer and is no departure); empty: none.
    Recorded in ``run.json`` and ``metrics.json``.
    """
    out = {}
    if scenario.reference_links_rule is not None:
        out['reference_links'] = scenario.reference_links_rule
    if scenario.impairments is not None and scenario.impairments.compensation == 'reference_motion':
        out['delay_compensation'] = 'reference_motion'
    if scenario.events and scenario.resilience.on_loss == 'reform':
        out['on_loss'] = 'reform'
    weight = scenario_gains(scenario, case).feedforward_weight
    if weight != 1.0:
        out['feedforward_weight'] = weight
    return out
