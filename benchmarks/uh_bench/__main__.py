"""``python -P -m uh_bench [--quick] [--sections ...] [--out FILE]`` (run by ``scripts/bench.sh``)."""
from __future__ import annotations

import json
import shutil
import sys
import tempfile
from pathlib import Path

from uh_runtime.command_line import ArgumentParser

from .suite import markdown, run_suite

SECTIONS = ('transport', 'paper', 'components', 'scaling', 'realtime', 'backends', 'campaign')


def main(argv=None) -> int:
    p = ArgumentParser(prog='bench.sh', description='Benchmarks of the UH stack: real-time factors, '
                                'scaling, real-time latency, per-step costs, memory. Writes a JSON results '
                                'file and prints a markdown table.')
    p.add_argument('--quick', action='store_true', help='short runs (under 5 minutes in all)')
    p.add_argument('--sections', nargs='+', choices=SECTIONS, default=list(SECTIONS),
                   help='sections to run (default: all)')
    p.add_argument('--out', default=str(Path(__file__).resolve().parents[1] / 'results' / 'latest.json'),
                   help='results file (default benchmarks/results/latest.json)')
    p.add_argument('--keep', default=None, metavar='DIR',
                   help='keep the runs (bags, logs, per-process records) in DIR instead of a temporary directory')
    args = p.parse_args(argv)
    mode = 'quick' if args.quick else 'full'
    if args.keep:
        workdir = Path(args.keep)
        if workdir.exists() and any(workdir.iterdir()):
            p.exit(2, f'bench.sh: error: --keep {workdir}: exists and is not empty\n')
    else:
        workdir = Path(tempfile.mkdtemp(prefix='uh-bench-'))
    try:
        results = run_suite(mode, workdir, sections=[s for s in SECTIONS if s in args.sections])
    except KeyboardInterrupt:
        print('bench.sh: interrupted', file=sys.stderr)
        return 130
    finally:
        if not args.keep:
            shutil.rmtree(workdir, ignore_errors=True)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results, indent=1, default=str) + '\n')
    print(markdown(results))
    print(f'[bench] results: {out}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
