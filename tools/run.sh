#!/usr/bin/env bash
# Run a command in the project's environment: the venv plus the colcon install of
# ROS_DISTRO (kilted by default, or jazzy; tools/distro.sh), both made by `make setup`.
set -eo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
# shellcheck source=tools/distro.sh
source "$ROOT/tools/distro.sh"
[ -f "$WS_INSTALL/setup.bash" ] || {
  echo "run.sh: ${WS_INSTALL#"$ROOT/"} is not built; run: make setup ROS_DISTRO=$DISTRO" >&2; exit 1; }
# shellcheck disable=SC1091
source "$VENV/bin/activate"
# shellcheck disable=SC1091
source "$WS_INSTALL/setup.bash"
export ROS_DISTRO=$DISTRO PYTHONUNBUFFERED=1
exec "$@"
