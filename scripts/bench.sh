#!/usr/bin/env bash
# Benchmarks of the UH stack: real-time factors (lockstep per process layout, in-process
# reference), scaling to 40 UHs, real-time latency, per-step costs and peak memory.
#   scripts/bench.sh [--quick] [--sections paper components scaling realtime] [--out FILE] [--keep DIR]
# Writes benchmarks/results/latest.json (or --out) and prints a markdown table; --quick runs
# every section with short runs (7 min 25 s in its last run). Sets up .venv on first use. See docs/performance.md.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/_venv.sh"
# relative --out and --keep are the caller's: uh_bench resolves them against this directory
export UH_BENCH_CALLER_DIR="$PWD"
cd "$REPO_ROOT"
export PYTHONPATH="$REPO_ROOT/benchmarks${PYTHONPATH:+:$PYTHONPATH}"
exec python -P -m uh_bench "$@"
