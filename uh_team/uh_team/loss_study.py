"""The loss study of docs/resilience.md: a scenario's team losing each UH in turn, re-forming and holding.

``python -P -m uh_team.loss_study [SCENARIO] [--time T] [--case CASE]`` flies the scenario once per UH
with that UH lost at ``T`` (default 30 s), with ``on_loss: reform`` and with ``on_loss: hold``, in
process, and prints the Markdown table of docs/resilience.md#measured (``reconfiguration`` of each
run's metrics). With ``--stuck`` it sticks each channel of each UH in turn at ``T`` (default 25 s)
instead and prints the table of docs/resilience.md#measured-a-stuck-actuator: when the UH's own
isolator found it, whether and when the others re-formed, the closest approach, with
``on_unable: leave`` (and, for the closest approach, ``stay``).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import yaml

from uh_core.layout import CHANNEL_NAMES, X_P_SLICE
from uh_topology.errors import ScenarioError
from uh_topology.scenario import load_scenario, scenario_from_mapping

from .metrics import metrics_from_arrays
from .separation_metrics import closest_pair_series
from .team_simulation import run_team_simulation

__all__ = ['main', 'loss_rows', 'stuck_rows']

PROG = 'python -m uh_team.loss_study'


def _with_loss(scenario, uh: int, time: float, on_loss: str):
    """Give ``scenario`` (loaded from its file) with UH ``uh`` lost at ``time`` and ``on_loss``."""
    data = yaml.safe_load(Path(scenario.source).read_text())
    data['events'] = [{'time': time, 'uh': uh, 'kind': 'lost'}]
    data['resilience'] = dict(data.get('resilience') or {}, on_loss=on_loss)
    return scenario_from_mapping(data, source=scenario.source, base_dir=Path(scenario.source).parent)


def _with_stuck(scenario, uh: int, channel: str, time: float, on_unable: str):
    """Give ``scenario`` (loaded from its file) with UH ``uh``'s ``channel`` stuck at ``time`` and ``on_unable``."""
    data = yaml.safe_load(Path(scenario.source).read_text())
    data['events'] = [{'time': time, 'uh': uh, 'kind': 'stuck', 'channel': channel}]
    data['resilience'] = dict(data.get('resilience') or {}, on_unable=on_unable)
    return scenario_from_mapping(data, source=scenario.source, base_dir=Path(scenario.source).parent)


def stuck_rows(scenario, time: float, case: str) -> list:
    """Give one row per UH and channel: ``(uh, channel, reconfiguration entry or None, closest staying, m)``."""
    rows = []
    for uh in scenario.ids:
        for channel in CHANNEL_NAMES:
            runs = {}
            for on_unable in ('leave', 'stay'):
                lossy = _with_stuck(scenario, uh, channel, time, on_unable)
                run = run_team_simulation(lossy, case)
                runs[on_unable] = (lossy, run)
            lossy, run = runs['leave']
            events = metrics_from_arrays(run.arrays(), lossy, case)['reconfiguration'] or [None]
            k0 = int(round(time / float(scenario.dt)))
            staying = float(np.min(closest_pair_series(runs['stay'][1].states[k0:, :, X_P_SLICE])))
            rows.append((uh, channel, events[0], staying))
    return rows


def _print_stuck(rows, time: float) -> None:
    print('| stuck | declared after (s) | channel found | re-formed after (s) | formation, last 10 s (m) '
          '| containment, last 10 s (m) | closest approach, leaving (m) | closest approach, staying (m) |')
    print('|---|---|---|---|---|---|---|---|')
    for uh, channel, e, staying in rows:
        if e is None:
            print(f'| UH{uh} {channel} | not found | - | - | - | - | - | {staying:.2f} |')
            continue
        after = {k: None if e[k] is None else e[k] - time for k in ('detected_at_s', 'reformed_at_s')}
        print(f'| UH{uh} {channel} | {_cell(after["detected_at_s"], ".2f")} | {e["channel"]} | '
              f'{_cell(after["reformed_at_s"], ".2f")} | {_cell(e["formation_error_last_10s_m"])} | '
              f'{_cell(e["containment_error_last_10s_m"])} | {_cell(e["min_separation_m"], ".2f")} | {staying:.2f} |')


def _cell(value, spec='.3f') -> str:
    return 'n/a' if value is None else format(value, spec)


def loss_rows(scenario, time: float, case: str) -> list:
    """Give one table row per UH and answer: the ``reconfiguration`` entry of the run losing it."""
    rows = []
    for uh in scenario.ids:
        for on_loss in ('reform', 'hold'):
            lossy = _with_loss(scenario, uh, time, on_loss)
            run = run_team_simulation(lossy, case)
            (event,) = metrics_from_arrays(run.arrays(), lossy, case)['reconfiguration']
            rows.append(event)
    return rows


def main(argv=None) -> int:
    """Print the loss study's table; returns the exit status."""
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.split('\n\n')[1])
    parser.add_argument('scenario', nargs='?', default='paper', help='bundled name or file (default paper)')
    parser.add_argument('--time', type=float, default=None,
                        help='when the UH is lost or the actuator sticks, s (default 30, with --stuck 25)')
    parser.add_argument('--case', default='proposed', help='controller case (default proposed)')
    parser.add_argument('--stuck', action='store_true', help='stick each channel of each UH instead of losing it')
    args = parser.parse_args(argv)
    time = args.time if args.time is not None else (25.0 if args.stuck else 30.0)
    try:
        scenario = load_scenario(args.scenario)
        if args.stuck:
            _print_stuck(stuck_rows(scenario, time, args.case), time)
            return 0
        rows = loss_rows(scenario, time, args.case)
    except (ScenarioError, ValueError) as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 2
    print('| lost | answer | agreed after (s) | re-formed after (s) | new leaders / followers '
          '| formation, last 10 s (m) '
          '| containment, last 10 s (m) | closest approach (m) | holding |')
    print('|---|---|---|---|---|---|---|---|---|')
    for e in rows:
        after = {k: None if e[k] is None else e[k] - e['time_s'] for k in ('agreed_at_s', 'reformed_at_s')}
        promoted = ''.join(f' (UH{uh} to slot {slot})' for slot, uh in e['promoted'].items())
        print(f'| UH{e["uh"]} | {e["on_loss"]} | {_cell(after["agreed_at_s"], ".2f")} | '
              f'{_cell(after["reformed_at_s"], ".2f")} | {e["leaders"]} / {e["followers"]}{promoted} | '
              f'{_cell(e["formation_error_last_10s_m"])} | {_cell(e["containment_error_last_10s_m"])} | '
              f'{_cell(e["min_separation_m"], ".2f")} | {", ".join("UH" + k for k in e["holding"]) or "-"} |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
