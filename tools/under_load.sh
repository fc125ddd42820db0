#!/usr/bin/env bash
# Run a command while one core is held busy by a CPU hog (a busy neighbour, as on a shared CI machine),
# e.g.  tools/under_load.sh make test
# The hog is a plain process at normal priority spinning in a loop; it is stopped when the command ends.
set -uo pipefail
python3 -c 'while True: pass' &
hog=$!
trap 'kill "$hog" 2>/dev/null; wait "$hog" 2>/dev/null' EXIT
"$@"
