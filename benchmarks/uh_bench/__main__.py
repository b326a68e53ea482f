"""``python -P -m uh_bench [--quick] [--sections ...] [--out FILE]`` (run by ``scripts/bench.sh``)."""
from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
from pathlib import Path

from uh_runtime.command_line import ArgumentParser

from .suite import markdown, run_suite

SECTIONS = ('transport', 'paper', 'components', 'scaling', 'realtime', 'backends', 'campaign')


def _given_path(text: str) -> Path:
    """Return a path given on the command line, a relative one taken from where bench.sh was started.

    bench.sh works from the repository root; it passes the caller's directory in ``UH_BENCH_CALLER_DIR``.
    """
    return Path(os.environ.get('UH_BENCH_CALLER_DIR', '.')) / text


def _check_paths(args) -> str | None:
    """Check --out and --keep before any benchmark runs (hours may be lost otherwise); return the problem or None."""
    for option, text in (('--out', args.out), ('--keep', args.keep)):
        if text is not None and not text.strip():
            return f"{option} '': give a {'file' if option == '--out' else 'directory'}"
    if args.keep:
        keep = _given_path(args.keep)
        if keep.exists() and not keep.is_dir():
            return f'--keep {args.keep}: exists and is not a directory'
        if keep.is_dir() and any(keep.iterdir()):
            return f'--keep {args.keep}: exists and is not empty; choose a new or empty directory'
    out = _given_path(args.out)
    if out.is_dir():
        return f'--out {args.out}: is a directory; give the results file (e.g. {args.out.rstrip("/")}/latest.json)'
    if out.parent.exists() and not out.parent.is_dir():
        return f'--out {args.out}: {out.parent} is a file, not a directory'
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        probe = out.parent / '.write_test'
        probe.write_text('')
        probe.unlink()
        if args.keep:
            _given_path(args.keep).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return f'{exc.filename}: cannot write there ({exc.strerror}); give --out and --keep paths you can write'
    return None


def main(argv=None) -> int:
    """Run the benchmark sections, write the JSON results to ``--out`` and print the markdown table; return the status.

    0 done; 2 bad ``--out`` or ``--keep`` (nothing ran); 130 interrupted.
    """
    p = ArgumentParser(prog='bench.sh', description='Benchmarks of the UH stack: real-time factors, '
                                'scaling, real-time latency, per-step costs, memory. Writes a JSON results '
                                'file and prints a markdown table.')
    p.add_argument('--quick', action='store_true', help='short runs (7 min 25 s in all in its last run, on 2 cores)')
    p.add_argument('--sections', nargs='+', choices=SECTIONS, default=list(SECTIONS),
                   help='sections to run (default: all)')
    p.add_argument('--out', default=str(Path(__file__).resolve().parents[1] / 'results' / 'latest.json'),
                   help='results file (default benchmarks/results/latest.json)')
    p.add_argument('--keep', default=None, metavar='DIR',
                   help='keep the runs (bags, logs, per-process records) in DIR instead of a temporary directory')
    args = p.parse_args(argv)
    mode = 'quick' if args.quick else 'full'
    problem = _check_paths(args)
    if problem:
        p.exit(2, f'bench.sh: error: {problem}\n')
    out = _given_path(args.out)
    if args.keep:
        workdir = _given_path(args.keep)
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
    out.write_text(json.dumps(results, indent=1, default=str) + '\n')
    print(markdown(results))
    print(f'[bench] results: {out}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
