# Sourced by the scripts: creates .venv at the repository root if missing (or if requirements.txt
# or a package changed since it was set up), installs the pinned dependencies and the project's
# packages, and activates it. On a ROS 2 machine use colcon instead (see README.md).
# UH_VENV and UH_REQUIREMENTS name another virtualenv and requirements file (scripts/_venv_rclpy.sh,
# scripts/_venv_secure.sh).
set -euo pipefail
REPO_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${UH_VENV:-$REPO_ROOT/.venv}"
REQUIREMENTS="${UH_REQUIREMENTS:-$REPO_ROOT/requirements.txt}"
PYTHON="${PYTHON:-python3}"
stamp_src() {
  cat "$REQUIREMENTS" "$REPO_ROOT"/uh_*/setup.py "$REPO_ROOT"/uh_msgs/msg/*.msg | sha256sum | cut -d' ' -f1
}
setup_step() {  # setup_step "what": one progress line with the seconds since the set-up started
  echo "[setup] $(( SECONDS - setup_started )) s: $1" >&2
}
if [ ! -x "$VENV/bin/python" ] || [ "$(cat "$VENV/.uh_stamp" 2>/dev/null)" != "$(stamp_src)" ]; then
  setup_started=$SECONDS
  echo "[setup] preparing virtualenv $VENV: about 730 MB, 1-2 minutes the first time (once; later runs start at once)" >&2
  if [ ! -x "$VENV/bin/python" ]; then
    setup_step "creating the virtualenv with $("$PYTHON" --version 2>&1)"
    "$PYTHON" -m venv "$VENV"
  fi
  setup_step "installing the pinned dependencies of $(basename "$REQUIREMENTS") (numpy, scipy, numba, cyclonedds, rosbags, mcap, matplotlib, ...)"
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check -r "$REQUIREMENTS"
  setup_step "installing the project's packages (uh_msgs, uh_runtime, ..., uh_bringup, uh_security)"
  # uh_msgs installs data files (the .msg definitions), so it is a regular install;
  # the Python packages are editable so a change in the tree takes effect without reinstalling.
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps "$REPO_ROOT/uh_msgs"
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps \
    -e "$REPO_ROOT/uh_runtime" -e "$REPO_ROOT/uh_core" -e "$REPO_ROOT/uh_topology" -e "$REPO_ROOT/uh_wire" \
    -e "$REPO_ROOT/uh_sim_node" -e "$REPO_ROOT/uh_controller_node"
  # the packages above both sides in a second step: a .venv made before uh_team existed has
  # uh-simulate in uh_controller_node's record, and reinstalling that package removes the script
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps \
    -e "$REPO_ROOT/uh_team" -e "$REPO_ROOT/uh_bringup"
  # uh-report and uh-campaign moved from uh_bringup to these two: installed after it, or reinstalling
  # an older uh_bringup would remove their scripts again; uh_security stands above uh_bringup
  "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps \
    -e "$REPO_ROOT/uh_report" -e "$REPO_ROOT/uh_campaign" -e "$REPO_ROOT/uh_security"
  stamp_src > "$VENV/.uh_stamp"
  setup_step "virtualenv ready ($(du -sh "$VENV" 2>/dev/null | cut -f1))"
fi
# shellcheck disable=SC1091
source "$VENV/bin/activate"
# numba compiles the model and control-law kernels on first use and caches them next to their
# sources (__pycache__). Warm that cache here, once per change of the kernel packages, so node
# processes started together load compiled kernels instead of each compiling them.
kernels_stamp() {
  find "$REPO_ROOT/uh_core/uh_core" "$REPO_ROOT/uh_sim_node/uh_sim_node" "$REPO_ROOT/uh_controller_node/uh_controller_node" \
    "$REPO_ROOT/uh_team/uh_team" \
    -maxdepth 1 -name '*.py' -printf '%p %T@ %s\n' | sort | cat - "$REPO_ROOT"/uh_*/setup.py | sha256sum | cut -d' ' -f1
}
if [ "$(cat "$VENV/.uh_kernels_stamp" 2>/dev/null)" != "$(kernels_stamp)" ]; then
  echo "[setup] compiling the numba kernels of the model and the control law (once; cached afterwards)" >&2
  python -P -m uh_team.compile_kernels >&2
  kernels_stamp > "$VENV/.uh_kernels_stamp"
fi
