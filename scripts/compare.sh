#!/usr/bin/env bash
# Run the proposed law, Case I and Case II (docs/control_law.md#comparison-cases) on the paper scenario and write one
# report comparing them (the paper's Figures 10-12 and the metrics table side by side).
#   scripts/compare.sh [--out DIR] [--duration S] [--simulate] [--scenario FILE|paper]
# Default: the distributed stack (scripts/run_formation.sh, lockstep clock, one process per node,
# recorded to MCAP), one case after the other. --simulate uses the in-process reference simulation
# (uh-simulate) instead: same controllers, same numbers, a few seconds per case.
# Output: DIR/proposed, DIR/case1, DIR/case2 (the runs) and DIR/report/ (report.md, index.html,
# metrics_table.csv, figures). DIR defaults to runs/compare-<date>-<time>.
set -euo pipefail
usage() { sed -n '2,9s/^# \{0,1\}//p' "${BASH_SOURCE[0]}"; }
OUT="" DURATION="" SIMULATE=0 SCENARIO="paper"
while [ $# -gt 0 ]; do
  case "$1" in
    --out) OUT="${2:?--out needs a directory}"; shift 2 ;;
    --duration) DURATION="${2:?--duration needs seconds}"; shift 2 ;;
    --scenario) SCENARIO="${2:?--scenario needs a file or name}"; shift 2 ;;
    --simulate) SIMULATE=1; shift ;;
    -h|--help) usage; exit 0 ;;
    *) echo "compare.sh: error: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done
source "$(dirname "${BASH_SOURCE[0]}")/_venv.sh"
OUT="${OUT:-$REPO_ROOT/runs/compare-$(date +%Y%m%d-%H%M%S)}"
if [ -e "$OUT" ] && [ -n "$(ls -A "$OUT" 2>/dev/null)" ]; then
  echo "compare.sh: error: --out $OUT exists and is not empty; choose a new directory" >&2
  exit 2
fi
mkdir -p "$OUT"
extra=()
[ -n "$DURATION" ] && extra+=(--duration "$DURATION")
for case in proposed case1 case2; do
  echo "[compare] $case" >&2
  if [ "$SIMULATE" = 1 ]; then
    uh-simulate --scenario "$SCENARIO" --case "$case" --out "$OUT/$case" "${extra[@]}"
  else
    "$REPO_ROOT/scripts/run_formation.sh" --scenario "$SCENARIO" --case "$case" --clock lockstep \
      --out "$OUT/$case" "${extra[@]}"
  fi
done
uh-report "$OUT/proposed" "$OUT/case1" "$OUT/case2" --scenario "$SCENARIO" --out "$OUT/report"
echo "[compare] report: $OUT/report/report.md and $OUT/report/index.html" >&2
