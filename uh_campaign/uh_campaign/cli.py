"""``uh-campaign``: run a Monte Carlo campaign of in-process team runs (docs/campaigns.md).

``uh-campaign SPEC --out DIR [--runs N] [--workers K] [--cluster ADDRESS] [--quiet]``

SPEC is a campaign spec file or the name of a bundled spec (``campaign_paper_faults``); its keys
are documented in :mod:`uh_campaign.spec`. Results go to ``DIR/campaign.sqlite``
(:mod:`uh_team.campaign_store`), the resolved scenario of every draw to ``DIR/scenarios/``.
Running the same command again on the same DIR resumes: stored runs are skipped.

Exit status: 0 every run stored (whatever their outcome), 1 the campaign could not go on (a
worker process died; what is done is saved), 2 bad input (spec, arguments, a DIR holding another
campaign, an unreachable cluster; nothing ran), 130 interrupted (what is done is saved; the
message says how to resume).
"""
from __future__ import annotations

import argparse
import shlex
import signal
import sys
import threading
from pathlib import Path

from uh_report.report import main as report_main
from uh_runtime.command_line import ArgumentParser, directory_argument
from uh_topology.errors import ScenarioError
from uh_topology.safety import add_safety_argument, safety_override

from .progress import Progress, success_text, summary_lines
from .runner import CampaignError, CampaignInterrupted, run_campaign
from .spec import load_spec

__all__ = ['main', 'build_parser', 'PROG']

PROG = 'uh-campaign'


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``uh-campaign``."""
    p = ArgumentParser(
        prog=PROG,
        description='Run a Monte Carlo campaign: random draws of a team scenario (initial states, faults, '
                    'model mismatch, disturbance, random graphs), each for every controller case and sweep '
                    'value, in-process runs in parallel, one row of metrics per run in DIR/campaign.sqlite. '
                    'Re-running the same command resumes an interrupted campaign.',
        epilog='Examples: uh-campaign campaign_paper_faults --out runs/mc_faults; '
               'uh-campaign my_campaign.yaml --out runs/mc --runs 20 --workers 2; '
               'uh-campaign campaign_delay_sweep --out runs/mc_delay --cluster tcp://10.0.0.5:8786. '
               'Exit status: 0 done, 1 could not go on (what is done is saved), 2 bad input, 130 interrupted. '
               'Spec keys: uh_campaign/uh_campaign/spec.py; report: uh-report DIR.')
    p.add_argument('spec', metavar='SPEC',
                   help='campaign spec YAML file, or the name of a bundled spec (campaign_paper_faults, '
                        'campaign_delay_sweep, campaign_delay_sweep_none, campaign_delay_sweep_jitter, '
                        'campaign_random_graphs, campaign_losses, campaign_losses_hold, ...)')
    p.add_argument('--out', required=True, type=directory_argument, metavar='DIR',
                   help='campaign directory: new or empty, or holding this same campaign (then it resumes)')
    p.add_argument('--runs', type=int, metavar='N',
                   help="number of draws, replacing the spec's runs; another number than the spec's is part "
                        "of the campaign's identity: resume with the same --runs")
    p.add_argument('--workers', type=int, metavar='K',
                   help='local worker processes (default: the number of CPUs); ignored with --cluster')
    p.add_argument('--cluster', metavar='ADDRESS',
                   help='run on the Dask cluster whose scheduler is at ADDRESS (e.g. tcp://host:8786) instead of '
                        'local processes. Every worker must have this project installed (same versions) and '
                        "be started from its environment, e.g. '.venv/bin/dask worker tcp://host:8786'")
    p.add_argument('--no-report', action='store_true',
                   help='do not write the report (uh-report DIR: DIR/report/) when every run is stored')
    p.add_argument('--quiet', action='store_true',
                   help='no progress and no summary on stderr (errors are still printed)')
    add_safety_argument(p)
    return p


def _fail(message: str, status: int = 2) -> int:
    print(f'{PROG}: error: {message}', file=sys.stderr)
    return status


def _resume_command(args) -> str:
    words = [PROG, args.spec, '--out', str(args.out)]
    if args.runs is not None:
        words += ['--runs', str(args.runs)]
    if args.cluster:
        words += ['--cluster', args.cluster]
    elif args.workers is not None:
        words += ['--workers', str(args.workers)]
    return ' '.join(shlex.quote(w) for w in words)


def main(argv=None) -> int:
    """Entry point of ``uh-campaign``; returns the exit status (see module docstring).

    Once every run is stored, the campaign's report is written (``uh-report DIR``: ``DIR/report/``)
    unless ``--no-report``, and its status is returned.
    """
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    if not str(args.spec).strip():
        return _fail("SPEC '': give a campaign spec YAML file or a bundled name")
    if args.workers is not None and args.workers < 1:
        return _fail(f'--workers must be >= 1, got {args.workers}')
    if args.runs is not None and args.runs < 1:
        return _fail(f'--runs must be >= 1, got {args.runs}')

    try:
        spec = load_spec(args.spec)
        if args.runs is not None:
            spec = spec.with_runs(args.runs)
        spec = spec.with_safety(safety_override(args.safety))
    except ScenarioError as exc:
        return _fail(str(exc))

    progress = Progress(sys.stderr, quiet=args.quiet, label=PROG)
    stop = threading.Event()

    def on_sigint(signum, frame):
        if stop.is_set():
            raise KeyboardInterrupt     # a second Ctrl-C: do not wait for the runs in flight
        stop.set()
        print(f'\n{PROG}: stopping: waiting for the runs in flight (Ctrl-C again to abort them)',
              file=sys.stderr, flush=True)

    previous = signal.signal(signal.SIGINT, on_sigint)
    try:
        outcome = run_campaign(spec, args.out, workers=args.workers, cluster=args.cluster, progress=progress,
                               stop=stop)
    except CampaignInterrupted as exc:
        done, total = exc.outcome.done, exc.outcome.total
        if done >= total:
            print(f'{PROG}: interrupted, but the runs in flight were the last ones: all {total} runs are stored '
                  f'in {args.out / "campaign.sqlite"}', file=sys.stderr)
        else:
            print(f'{PROG}: interrupted: {done} of {total} runs stored in {args.out / "campaign.sqlite"}; '
                  f'resume with:\n  {_resume_command(args)}', file=sys.stderr)
        return 130
    except KeyboardInterrupt:
        print(f'{PROG}: aborted; the runs stored so far are in {args.out / "campaign.sqlite"}; resume with:\n'
              f'  {_resume_command(args)}', file=sys.stderr)
        return 130
    except CampaignError as exc:
        return _fail(f'{exc}' + (f'; resume with: {_resume_command(args)}' if exc.status == 1 else ''), exc.status)
    finally:
        signal.signal(signal.SIGINT, previous)

    if not args.quiet:
        out = sys.stderr
        print(f'{PROG}: {spec.name}: {outcome.done}/{outcome.total} runs stored ({outcome.done - outcome.skipped} '
              f'now, {outcome.failures} of them not ok) in {outcome.wall_time_s:.1f} s; success: '
              f'{success_text(spec)}', file=out)
        for line in summary_lines(args.out, spec):
            print(f'  {line}', file=out)
        print(f'{PROG}: results {Path(args.out) / "campaign.sqlite"}, resolved scenarios '
              f'{Path(args.out) / "scenarios"}/; report: uh-report {args.out}', file=out)
    if not args.no_report:
        return report_main([str(args.out)])
    return 0


if __name__ == '__main__':
    sys.exit(main())
