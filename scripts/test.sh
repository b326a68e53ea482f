#!/usr/bin/env bash
# Runs the test suite: sets up .venv (pinned dependencies + the project's packages) if needed,
# then pytest. Extra arguments go to pytest, e.g. scripts/test.sh -k topology -x
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/_venv.sh"
cd "$REPO_ROOT"
exec python -P -m pytest "$@"
