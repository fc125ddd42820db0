#!/usr/bin/env bash
# make setup: everything from nothing, idempotent, quick when nothing changed.
#   1. Debian packages the build needs (installed when root, else named).
#   2. A venv with every Python dependency pinned in the distribution's lock file.
#   3. The known fixes the ROS 2 PyPI wheels need (shared/docs/ros2-from-pypi.md).
#   4. colcon build of ros_ws/ (only when a source file changed since the last build).
#   5. The npm packages of the Foxglove decoding test (tests/foxglove, pinned by its package-lock.json).
# The ROS 2 distribution is ROS_DISTRO (kilted by default, or jazzy; tools/distro.sh): each has its own
# lock file, venv and colcon build/install/log folders, so both can be set up side by side.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
PYTHON=${PYTHON:-python3.11}
command -v "$PYTHON" >/dev/null 2>&1 || PYTHON=python3
# shellcheck source=tools/distro.sh
source tools/distro.sh
say() { printf 'setup[%s]: %s\n' "$DISTRO" "$*"; }

# --- 1. Debian packages -------------------------------------------------------
# Each entry: a check that passes when the thing is present, and the package that provides it.
missing=()
need() { eval "$1" >/dev/null 2>&1 || missing+=("$2"); }
need "command -v cmake" cmake
need "command -v g++" g++
need "command -v make" make
need "$PYTHON -c 'import sysconfig,os,sys; sys.exit(not os.path.exists(os.path.join(sysconfig.get_paths()[\"include\"], \"Python.h\")))'" python3-dev
need "$PYTHON -c 'import ensurepip, venv'" python3-venv
# The rig firmware (avr-gcc, avr-libc, avrdude to flash) and its simulation in the loop (simavr).
need "command -v avr-gcc" gcc-avr
need "command -v avr-objcopy" binutils-avr
need "test -f /usr/lib/avr/include/avr/io.h" avr-libc
need "command -v avrdude" avrdude
need "pkg-config --exists simavr" libsimavr-dev
need "pkg-config --exists libelf" libelf-dev
need "command -v pkg-config" pkg-config
# Foxglove's own decoders (npm) for the test that decodes our bags as Foxglove does.
need "command -v node" nodejs
need "command -v npm" npm
if [ ${#missing[@]} -gt 0 ]; then
  if [ "$(id -u)" = 0 ]; then
    say "installing Debian packages: ${missing[*]}"
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
  else
    echo "setup: missing Debian packages: ${missing[*]}" >&2
    echo "setup: run as root, or: sudo apt-get install ${missing[*]}" >&2
    exit 1
  fi
fi
"$PYTHON" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' || {
  echo "setup: Python 3.11 is required (the ROS 2 wheels are cp311); found $($PYTHON --version)" >&2; exit 1; }

# --- 2. virtual environment ---------------------------------------------------
[ -x "$VENV/bin/python" ] || { say "creating ${VENV#"$ROOT/"}"; "$PYTHON" -m venv "$VENV"; }
req_hash=$(sha256sum "$LOCK" | cut -d' ' -f1)
if [ "$(cat "$VENV/.requirements.sha256" 2>/dev/null)" != "$req_hash" ]; then
  say "installing pinned Python dependencies (${LOCK#"$ROOT/"})"
  "$VENV/bin/python" -m pip install -q --disable-pip-version-check --upgrade pip
  "$VENV/bin/python" -m pip install -q --disable-pip-version-check -r "$LOCK"
  echo "$req_hash" > "$VENV/.requirements.sha256"
fi

# --- 3. fixes the ROS 2 wheels need --------------------------------------------
"$VENV/bin/python" tools/fix_ros_wheels.py --venv "$VENV" >/dev/null

# --- 4. colcon build ----------------------------------------------------------
# One build at a time (several shells may run make at once), and the stamp
# records when the build *started*, so a source edited during a build still
# triggers the next one.
mkdir -p "$WS_INSTALL"
exec 9>ros_ws/.build.lock
flock 9
stamp=$WS_INSTALL/.build-stamp
# A file moved or deleted in the sources would linger in build/ and install/
# (colcon's setuptools build copies, it does not prune): when the list of
# source files differs from the last build's, the Python packages are rebuilt
# from scratch.
listing=$WS_INSTALL/.source-files
current=$(cd ros_ws/src && find . -name '*.py' -o -name '*.msg' -o -name '*.yaml' | LC_ALL=C sort | sha256sum)
if [ -f "$listing" ] && [ "$(cat "$listing")" != "$current" ]; then
  say "source files added, moved or removed: clean rebuild of the Python packages"
  for pkg in worm_model worm_rig_driver torque_estimator; do
    rm -rf "${WS_BUILD:?}/$pkg" "${WS_INSTALL:?}/$pkg"
  done
  rm -f "$stamp"
fi
if [ ! -f "$stamp" ] || [ -n "$(find ros_ws/src -newer "$stamp" -print -quit)" ] \
   || [ "$LOCK" -nt "$stamp" ]; then
  say "colcon build of ros_ws (log: ${WS_LOG#"$ROOT/"}/latest_build)"
  touch "$stamp.new"
  (
    cd ros_ws
    # shellcheck disable=SC1091
    source "$VENV/bin/activate"
    export AMENT_PREFIX_PATH=$VENV CMAKE_PREFIX_PATH=$VENV
    unset COLCON_PREFIX_PATH
    colcon --log-base "$WS_LOG" build --build-base "$WS_BUILD" --install-base "$WS_INSTALL" \
      --event-handlers console_cohesion- console_stderr- \
      --cmake-args -DBUILD_TESTING=OFF -DPython3_EXECUTABLE="$VENV/bin/python" >/dev/null \
      || { echo "setup: colcon build failed; see ${WS_LOG#"$ROOT/"}/latest_build" >&2; exit 1; }
  )
  mv "$stamp.new" "$stamp"
  echo "$current" > "$listing"
fi
[ -f "$listing" ] || echo "$current" > "$listing"
exec 9>&-

# --- 5. npm packages of the Foxglove test ----------------------------------------
# `npm ci` installs exactly package-lock.json; redone when the lock file changes.
FOXGLOVE=tests/foxglove
npm_hash=$(sha256sum "$FOXGLOVE/package-lock.json" | cut -d' ' -f1)
if [ "$(cat "$FOXGLOVE/node_modules/.package-lock.sha256" 2>/dev/null)" != "$npm_hash" ]; then
  say "installing the Foxglove test's npm packages (npm ci in $FOXGLOVE)"
  (cd "$FOXGLOVE" && npm ci --silent --no-audit --no-fund >/dev/null)
  echo "$npm_hash" > "$FOXGLOVE/node_modules/.package-lock.sha256"
fi
say "ready (source ${VENV#"$ROOT/"}/bin/activate && source ${WS_INSTALL#"$ROOT/"}/setup.bash)"
