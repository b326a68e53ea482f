# Sourced by scripts/test.sh (the real-rclpy tier) and by scripts/run_formation.sh with UH_ROS_WHEELS=1:
# creates .venv-rclpy, a Python 3.12 virtualenv with ROS 2 Jazzy's rclpy on Fast DDS from PyPI's
# ros-jazzy-* wheels (pinned in constraints-ros-wheels.txt; unofficial, for testing only), the project's
# packages, and uh_msgs built by rosidl with plain cmake; then activates it. Reused while nothing it was
# built from changed (stamps, as scripts/_venv.sh). Python 3.12: python3.12 on PATH, else pyenv's.
set -euo pipefail
REPO_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
find_python312() {
  local candidate
  for candidate in "${UH_PYTHON312:-}" "$(command -v python3.12 || true)" \
      "${PYENV_ROOT:-$HOME/.pyenv}"/versions/3.12*/bin/python3.12; do
    if [ -n "$candidate" ] && [ -x "$candidate" ] && "$candidate" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 12))' 2>/dev/null; then
      echo "$candidate"
      return 0
    fi
  done
  return 1
}
if ! PYTHON="$(find_python312)"; then
  echo "the real-rclpy tier needs Python 3.12 (the ROS 2 Jazzy wheels are cp312 only): none found as python3.12 on" \
    "PATH, UH_PYTHON312 or ${PYENV_ROOT:-$HOME/.pyenv}/versions/3.12*; install one (e.g. pyenv install 3.12)" >&2
  return 2 2>/dev/null || exit 2
fi
export PYTHON
export UH_VENV="${UH_RCLPY_VENV:-$REPO_ROOT/.venv-rclpy}"
# the interpreter, the project's pinned dependencies and packages, the numba kernels: as for .venv
# shellcheck source=_venv.sh
source "$REPO_ROOT/scripts/_venv.sh"
rclpy_stamp() {
  cat "$REPO_ROOT/constraints-ros-wheels.txt" "$REPO_ROOT/requirements.txt" "$REPO_ROOT/scripts/_venv_rclpy.sh" \
    "$REPO_ROOT/uh_msgs/CMakeLists.txt" "$REPO_ROOT/uh_msgs/package.xml" "$REPO_ROOT"/uh_msgs/msg/*.msg \
    "$UH_VENV/.uh_stamp" | sha256sum | cut -d' ' -f1
}
if [ "$(cat "$UH_VENV/.uh_rclpy_stamp" 2>/dev/null)" != "$(rclpy_stamp)" ]; then
  rclpy_started=$SECONDS
  rclpy_step() { echo "[setup-rclpy] $(( SECONDS - rclpy_started )) s: $1" >&2; }
  command -v cmake >/dev/null && command -v c++ >/dev/null || {
    echo "the real-rclpy tier builds uh_msgs with cmake and a C/C++ compiler: install cmake and g++" >&2
    return 2 2>/dev/null || exit 2
  }
  rclpy_step "installing ROS 2 Jazzy's rclpy (Fast DDS), message and rosidl packages from PyPI (about 250 MB)"
  # every name of the constraints file that is not a dependency of another: the ros-jazzy-* and catkin-pkg
  mapfile -t wanted < <(grep -E '^(ros-jazzy-|catkin-pkg)' "$REPO_ROOT/constraints-ros-wheels.txt" | cut -d= -f1)
  wanted=("${wanted[@]/ros-jazzy-rclpy/ros-jazzy-rclpy[fastrtps]}")
  # pip warns about index locations of the machine's configuration that do not exist: noise, not faults
  "$UH_VENV/bin/python" -m pip install --quiet --disable-pip-version-check "${wanted[@]}" \
    -c "$REPO_ROOT/constraints-ros-wheels.txt" -c "$REPO_ROOT/requirements.txt" 2>&1 | grep -v '^WARNING: Location' >&2 || true
  "$UH_VENV/bin/python" -c 'import rclpy, std_msgs.msg, nav_msgs.msg, diagnostic_msgs.msg' \
    || { echo "[setup-rclpy] the ROS 2 wheels did not install (output above)" >&2; return 1 2>/dev/null || exit 1; }
  # The wheels' exported CMake targets name the include directories of the machine that built them
  # (/opt/python/cp312-cp312/...): point them at this interpreter's and numpy's.
  py_include="$("$UH_VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')"
  np_include="$("$UH_VENV/bin/python" -c 'import numpy; print(numpy.get_include())')"
  { grep -rl --include='*.cmake' '/opt/python/' "$UH_VENV/share" || true; } | xargs -r sed -i \
    -e "s#/opt/python/cp312-cp312/lib/python3.12/site-packages/numpy/_core/include#$np_include#g" \
    -e "s#/opt/python/cp312-cp312/include/python3.12#$py_include#g"
  rclpy_step "generating and building uh_msgs with rosidl and cmake"
  build="$UH_VENV/build-uh_msgs"
  rm -rf "$build"
  PATH="$UH_VENV/bin:$PATH" cmake -S "$REPO_ROOT/uh_msgs" -B "$build" -DCMAKE_PREFIX_PATH="$UH_VENV" \
    -DCMAKE_INSTALL_PREFIX="$UH_VENV" -DPython3_EXECUTABLE="$UH_VENV/bin/python" -DBUILD_TESTING=OFF \
    > "$build.log" 2>&1 \
    && PATH="$UH_VENV/bin:$PATH" cmake --build "$build" -j "$(nproc)" >> "$build.log" 2>&1 \
    && cmake --install "$build" >> "$build.log" 2>&1 \
    || { tail -30 "$build.log" >&2; echo "[setup-rclpy] building uh_msgs failed: $build.log" >&2
         return 1 2>/dev/null || exit 1; }
  "$UH_VENV/bin/python" -c 'import rclpy; from uh_msgs.msg import UHState' \
    || { echo "[setup-rclpy] uh_msgs built but does not import" >&2; return 1 2>/dev/null || exit 1; }
  rclpy_stamp > "$UH_VENV/.uh_rclpy_stamp"
  rclpy_step "rclpy virtualenv ready ($(du -sh "$UH_VENV" 2>/dev/null | cut -f1))"
fi
