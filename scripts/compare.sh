#!/usr/bin/env bash
# Run the proposed law, Case I and Case II (docs/control_law.md#comparison-cases) on the paper scenario and write one
# report comparing them (the paper's Figures 10-12 and the metrics table side by side).
#   scripts/compare.sh [--out DIR] [--duration S] [--simulate] [--scenario FILE|paper]
# Default: the distributed stack (scripts/run_formation.sh, lockstep clock, one process per node,
# recorded to MCAP), one case after the other. --simulate uses the in-process reference simulation
# (uh-simulate) instead: same controllers, same numbers, a few seconds per case.
# Output: DIR/proposed, DIR/case1, DIR/case2 (the runs) and DIR/report/ (report.md, index.html,
# metrics_table.csv, figures). DIR defaults to runs/compare-<date>-<time>.
# Exit status: 0 done, 2 bad input (checked before the first run: nothing ran), else the status of
# the run or report that failed (uh_bringup/uh_bringup/compare.py).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/_venv.sh"
exec python -P -m uh_bringup.compare --default-root "$REPO_ROOT/runs" "$@"
