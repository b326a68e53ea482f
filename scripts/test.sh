#!/usr/bin/env bash
# Runs the lint step and the test suite: sets up .venv (pinned dependencies + the project's packages)
# if needed, checks the code with ruff (ruff.toml: pycodestyle, pyflakes, pep257 docstrings), then
# runs pytest. Extra arguments go to pytest, e.g. scripts/test.sh -k topology -x
#   scripts/test.sh --quick   the quick tier: every package, no DDS processes and no long runs
#                             (under 2 minutes on 2 cores; the full suite is the default and CI's)
set -euo pipefail
if [ "${1:-}" = "--quick" ]; then
  shift
  export UH_TEST_TIER=quick
  set -- -m "not slow and not dds" "$@"
fi
source "$(dirname "${BASH_SOURCE[0]}")/_venv.sh"
cd "$REPO_ROOT"
if ! python -P -m ruff check --quiet .; then
  echo "lint: the findings above break the rules of ruff.toml (.venv/bin/ruff check --fix repairs some of them)" >&2
  exit 1
fi
exec python -P -m pytest "$@"
