#!/usr/bin/env bash
# Run a command in the project's environment: the venv plus the colcon install.
set -eo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
# shellcheck disable=SC1091
source "$ROOT/.venv/bin/activate"
# shellcheck disable=SC1091
source "$ROOT/ros_ws/install/setup.bash"
export PYTHONUNBUFFERED=1
exec "$@"
