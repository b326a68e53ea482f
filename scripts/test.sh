#!/usr/bin/env bash
# Runs the lint step and the test suite: sets up .venv (pinned dependencies + the project's packages)
# if needed, checks the code with ruff (ruff.toml: pycodestyle, pyflakes, bugbear, pep257 docstrings
# on every public definition outside tests/, isort's import order), then runs pytest, then the real-rclpy tier and
# the secure tier. Run whole, the main suite's tests without DDS processes run on two pytest-xdist workers, then
# those with DDS processes one at a time. Extra arguments go to one pytest run, e.g. scripts/test.sh -k topology -x
#   scripts/test.sh --quick   the quick tier: every package, no DDS processes and no long runs
#                             (under 2 minutes on 2 cores; the full suite is the default and CI's)
#   scripts/test.sh --rclpy   only the real-rclpy tier (extra arguments go to its pytest)
#   scripts/test.sh --secure  only the secure tier: the DDS Security attacks and secure runs (tests marked secure)
#                             in .venv-secure, Cyclone DDS 0.10.2 with its security plugins (scripts/_venv_secure.sh
#                             builds it; docs/security.md); it follows the rclpy tier in a whole run
#                             (UH_TEST_SECURE=0 leaves it out)
# The real-rclpy tier (docs/testing.md#the-real-rclpy-tier) runs the tests marked rclpy_real in
# .venv-rclpy, a Python 3.12 virtualenv with ROS 2 Jazzy's rclpy on Fast DDS from PyPI's unofficial
# wheels (scripts/_venv_rclpy.sh builds it on first use). It follows the main suite when that is run
# whole (no arguments); UH_TEST_RCLPY=0 leaves it out.
set -euo pipefail
here="$(dirname "${BASH_SOURCE[0]}")"
rclpy_tier() {  # in a subshell: the tier's virtualenv is activated there only
  ( source "$here/_venv_rclpy.sh" && cd "$REPO_ROOT" && echo "[test] the real-rclpy tier (.venv-rclpy)" >&2 \
    && python -P -m pytest -m rclpy_real "$@" )
}
secure_tier() {  # in a subshell: the tier's virtualenv is activated there only
  ( source "$here/_venv_secure.sh" && cd "$REPO_ROOT" && echo "[test] the secure tier (.venv-secure)" >&2 \
    && python -P -m pytest -m secure "$@" )
}
if [ "${1:-}" = "--secure" ]; then
  shift
  secure_tier "$@"
  exit
fi
if [ "${1:-}" = "--rclpy" ]; then
  shift
  rclpy_tier "$@"
  exit
fi
tier=full
if [ "${1:-}" = "--quick" ]; then
  shift
  tier=quick
  export UH_TEST_TIER=quick
  set -- -m "not slow and not dds" "$@"
fi
whole=$(( $# == 0 ))
source "$here/_venv.sh"
cd "$REPO_ROOT"
if ! python -P -m ruff check --quiet .; then
  echo "lint: the findings above break the rules of ruff.toml (.venv/bin/ruff check --fix repairs some of them)" >&2
  exit 1
fi
if [ "$tier" = quick ] || [ "$whole" = 0 ] || [ "${UH_TEST_RCLPY:-1}" = 0 ]; then
  exec python -P -m pytest "$@"
fi
status=0
# the whole main suite in two runs: the tests without DDS processes on two pytest-xdist workers (pure
# computation: about 40 % less wall time on 2 cores), then those with DDS processes one at a time, as their
# realtime runs keep their period only on a machine the suite does not load itself
echo "[test] the tests without DDS processes (two workers)" >&2
python -P -m pytest -m "not dds" -n 2 || status=$?
echo "[test] the tests with DDS processes (one at a time)" >&2
python -P -m pytest -m dds || status=$(( status ? status : $? ))
rclpy_tier || status=$(( status ? status : $? ))
if [ "${UH_TEST_SECURE:-1}" != 0 ]; then
  secure_tier || status=$(( status ? status : $? ))
fi
exit "$status"
