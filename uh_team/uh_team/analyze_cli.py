"""``uh-analyze``: the delay margin of a scenario's team, before flying it (docs/delay.md#delay-margin).

    uh-analyze SCENARIO [--case proposed|case1|case2] [--json] [--most N] [--measure]

Prints, for the scenario's graph, gains and airframe, the largest uniform link delay (steps and ms)
at which the linearised team stays stable with and without prediction, the mode that goes unstable
first (frequency, the UHs it lives on), the slowest mode at zero delay (its time constant), the
oldest state the scenario's own links deliver against the margin, and the largest feed-forward
weight whose margin covers it. ``--json`` prints the same as one object. ``--measure`` also flies the
team in process at the delays around each onset and prints the measured onset beside the predicted
one. Exit status: 0, or 2 for a scenario the loader refuses (its own message) or a bad argument.
"""
from __future__ import annotations

import json
import sys

from uh_controller_node.delay_margin import (
    MODELLED,
    MOST_STEPS,
    applied_compensation,
    covering_feedforward_weight,
    modelled,
    scenario_link_age,
    scenario_margin,
)
from uh_controller_node.gains import CASES
from uh_runtime.command_line import ArgumentParser
from uh_topology.errors import ScenarioError
from uh_topology.scenario import load_scenario

from .delay_measure import measured_onset
from .departures import scenario_departures

PROG = 'uh-analyze'


def build_parser() -> ArgumentParser:
    """Build the command line of ``uh-analyze``."""
    p = ArgumentParser(prog=PROG, description=__doc__.split('\n\n')[0].split(': ', 1)[1])
    p.add_argument('scenario', help='scenario file or bundled name (paper, square, wide, ...)')
    p.add_argument('--case', choices=CASES, default='proposed', help='comparison case (default: proposed)')
    p.add_argument('--json', action='store_true', help='print one JSON object instead of text')
    p.add_argument('--most', type=int, default=MOST_STEPS, metavar='N',
                   help=f'scan delays 0..N steps (default {MOST_STEPS}); beyond: none found')
    p.add_argument('--measure', action='store_true',
                   help='also fly the team in process around each onset and report the measured onset')
    return p


def analysis(scenario, case: str, most: int, measure: bool) -> dict:
    """Everything ``uh-analyze`` prints, as one JSON-ready mapping."""
    margin = scenario_margin(scenario, case, most)
    out = {'scenario': scenario.name, 'case': case, **margin.as_json(),
           'departures': scenario_departures(scenario, case)}
    age = scenario_link_age(scenario)
    compensation = applied_compensation(scenario, realtime=False)
    limit = margin.margin_steps[modelled(compensation)]
    out['links'] = {'oldest_state_steps': age, 'compensation': compensation,
                    'within_margin': limit is None or age <= limit}
    out['covering_feedforward_weight'] = covering_feedforward_weight(scenario, case, max(age, 0), compensation)
    if measure:
        out['measured_onset_steps'] = {}
        for c in MODELLED:
            first = margin.first_unstable[c]
            top = (first if first is not None else most) + 3
            out['measured_onset_steps'][c] = measured_onset(scenario, case, c, range(max(0, top - 6), top + 1))
    return out


def text_lines(result: dict) -> list:
    """Write the text report of :func:`analysis`."""
    dt_ms = result['dt_s'] * 1000.0
    lines = [f"{result['scenario']} / {result['case']}: delay margin (the same delay on every link; "
             'docs/delay.md#delay-margin)']
    for c in MODELLED:
        steps, mode = result['margin_steps'][c], result['onset_mode'][c]
        if steps is None:
            text = f"no delay up to {result['most_steps']} steps destabilises it"
        elif steps < 0:
            text = 'unstable without delay'
        else:
            text = (f'{steps} steps ({steps * dt_ms:g} ms); from {steps + 1} steps a {mode["frequency_hz"]:.2f} Hz '
                    f'mode grows on UH {", ".join(map(str, mode["uhs"]))} ({mode["axis"]})')
        measured = result.get('measured_onset_steps', {}).get(c, 'skip')
        if measured != 'skip':
            text += f'; measured onset: {measured if measured is not None else "none"}'
        lines.append(f'  {"with prediction" if c == "predict" else "without prediction":20s} {text}')
    slow = result['slowest_mode']
    lines.append(f'  {"slowest mode":20s} time constant {slow["time_constant_s"]:.2f} s at zero delay '
                 f'(UH {", ".join(map(str, slow["uhs"]))})')
    links = result['links']
    verdict = 'within the margin' if links['within_margin'] else 'BEYOND the margin'
    lines.append(f'  {"scenario links":20s} states up to {links["oldest_state_steps"]} steps old '
                 f'({links["compensation"]}): {verdict}')
    weight = result['covering_feedforward_weight']
    lines.append(f'  {"feed-forward weight":20s} ' + (f'{weight:g} covers the scenario\'s links (gains key '
                 'feedforward_weight; docs/delay.md#remedies)' if weight is not None else 'none covers them'))
    if result['departures']:
        lines.append(f'  {"departures":20s} ' + ', '.join(f'{k}: {v}' for k, v in result['departures'].items()))
    return lines


def main(argv=None) -> int:
    """Entry point of ``uh-analyze``; returns the exit status (see module docstring)."""
    args = build_parser().parse_args(argv)
    if args.most < 0:
        print(f'{PROG}: error: --most must be a whole number of steps >= 0, got {args.most}', file=sys.stderr)
        return 2
    try:
        scenario = load_scenario(args.scenario)
        result = analysis(scenario, args.case, args.most, args.measure)
    except ScenarioError as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f'{PROG}: interrupted', file=sys.stderr)
        return 130
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print('\n'.join(text_lines(result)))
    return 0


if __name__ == '__main__':
    sys.exit(main())
