# Sourced by scripts/test.sh --secure (the secure tier, docs/security.md): creates .venv-secure, a Python 3.11
# virtualenv with the project's pinned dependencies and packages on Cyclone DDS 0.10.2 with DDS Security, then
# activates it. PyPI's 11.0.1 wheel of requirements.txt has no security plugins; Debian 12's cyclonedds-dev
# (0.10.2) ships them, so the cyclonedds sdist pinned in requirements-secure.txt is built against it
# (apt-get installs cyclonedds-dev when it is missing). Everything else comes from requirements.txt less its
# cyclonedds line, through scripts/_venv.sh. Reused while nothing it was built from changed (stamps).
set -euo pipefail
REPO_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SECURE_VENV="${UH_SECURE_VENV:-$REPO_ROOT/.venv-secure}"
find_python311() {
  local candidate
  for candidate in "${UH_PYTHON311:-}" "$(command -v python3.11 || true)" \
      "${PYENV_ROOT:-$HOME/.pyenv}"/versions/3.11*/bin/python3.11; do
    if [ -n "$candidate" ] && [ -x "$candidate" ] && "$candidate" -c 'import sys, venv, ensurepip; sys.exit(sys.version_info[:2] != (3, 11))' 2>/dev/null; then
      echo "$candidate"
      return 0
    fi
  done
  return 1
}
cyclonedds_dev_version() {  # the installed version of Debian's cyclonedds-dev, empty when it is not installed
  dpkg-query -W -f='${db:Status-Status} ${Version}\n' cyclonedds-dev 2>/dev/null | sed -n 's/^installed //p'
}
secure_stamp() {
  { cat "$REPO_ROOT/requirements-secure.txt" "$REPO_ROOT/scripts/_venv_secure.sh"; cyclonedds_dev_version; } \
    | sha256sum | cut -d' ' -f1
}
secure_started=$SECONDS
secure_step() { echo "[setup-secure] $(( SECONDS - secure_started )) s: $1" >&2; }
if [ ! -x "$SECURE_VENV/bin/python" ] || [ "$(cat "$SECURE_VENV/.uh_secure_stamp" 2>/dev/null)" != "$(secure_stamp)" ]; then
  if ! PYTHON="$(find_python311)"; then
    echo "the secure tier needs Python 3.11 with venv (python3.11 on PATH, UH_PYTHON311 or" \
      "${PYENV_ROOT:-$HOME/.pyenv}/versions/3.11*): none found; install one (e.g. apt-get install python3.11-venv)" >&2
    return 2 2>/dev/null || exit 2
  fi
  command -v cc >/dev/null || {
    echo "the secure tier builds the cyclonedds sdist with a C compiler: install gcc" >&2
    return 2 2>/dev/null || exit 2
  }
  if [ -z "$(cyclonedds_dev_version)" ]; then
    [ "$(id -u)" = 0 ] || {
      echo "the secure tier needs Debian's cyclonedds-dev (Cyclone DDS 0.10.2 with its security plugins):" \
        "run 'sudo apt-get install cyclonedds-dev', then this again" >&2
      return 2 2>/dev/null || exit 2
    }
    secure_step "installing Debian's cyclonedds-dev (Cyclone DDS 0.10.2 and its security plugins) with apt-get"
    apt_log="$(mktemp)"
    if ! DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends cyclonedds-dev > "$apt_log" 2>&1; then
      secure_step "apt-get did not know cyclonedds-dev: updating its package lists first"
      { apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends cyclonedds-dev; } \
        > "$apt_log" 2>&1 || { tail -20 "$apt_log" >&2; echo "[setup-secure] apt-get install cyclonedds-dev failed" >&2
                               return 1 2>/dev/null || exit 1; }
    fi
    rm -f "$apt_log"
  fi
  case "$(cyclonedds_dev_version)" in
    0.10.*) ;;
    *) echo "[setup-secure] cyclonedds-dev $(cyclonedds_dev_version) is installed; secure mode is built and tested on" \
         "0.10.x (Debian 12's 0.10.2), the line of requirements-secure.txt" >&2
       return 2 2>/dev/null || exit 2 ;;
  esac
  if [ ! -x "$SECURE_VENV/bin/python" ]; then
    secure_step "creating the virtualenv $SECURE_VENV with $("$PYTHON" --version 2>&1)"
    "$PYTHON" -m venv "$SECURE_VENV"
  fi
  # The sdist looks for $CYCLONEDDS_HOME/lib/libddsc.so only; Debian keeps it in lib/<multiarch>. A folder of
  # links gives it that layout for the build alone: at run time the binding finds libddsc through the loader
  # (CYCLONEDDS_HOME=/usr would make it look for /usr/lib/libddsc.so, which does not exist).
  home="$SECURE_VENV/cyclonedds-home"
  mkdir -p "$home"
  ln -sfn /usr/include "$home/include"
  ln -sfn /usr/bin "$home/bin"
  ln -sfn "/usr/lib/$(dpkg-architecture -qDEB_HOST_MULTIARCH 2>/dev/null || gcc -print-multiarch)" "$home/lib"
  secure_step "building $(grep -E '^cyclonedds==' "$REPO_ROOT/requirements-secure.txt") from its sdist against cyclonedds-dev $(cyclonedds_dev_version)"
  CYCLONEDDS_HOME="$home" "$SECURE_VENV/bin/python" -m pip install --quiet --disable-pip-version-check --no-cache-dir \
    --no-binary cyclonedds -r "$REPO_ROOT/requirements-secure.txt"
  env -u CYCLONEDDS_HOME "$SECURE_VENV/bin/python" -P -c 'import cyclonedds.domain, cyclonedds.qos' \
    || { echo "[setup-secure] the cyclonedds binding built but does not import" >&2; return 1 2>/dev/null || exit 1; }
  secure_stamp > "$SECURE_VENV/.uh_secure_stamp"
  secure_step "Cyclone DDS 0.10.2 with DDS Security ready"
fi
# the project's pinned dependencies (less cyclonedds) and packages, and the numba kernels: as for .venv
grep -v -E '^cyclonedds==' "$REPO_ROOT/requirements.txt" > "$SECURE_VENV/requirements-less-cyclonedds.txt"
export UH_VENV="$SECURE_VENV" UH_REQUIREMENTS="$SECURE_VENV/requirements-less-cyclonedds.txt"
PYTHON="$(find_python311 || echo python3.11)"   # _venv.sh creates no virtualenv here: it exists
export PYTHON
# shellcheck source=_venv.sh
source "$REPO_ROOT/scripts/_venv.sh"
