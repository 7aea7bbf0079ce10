#!/usr/bin/env bash
# Stop a run started with `ost_up.sh --background` (or `ost up --background`):
#   bringup_scripts/ost_down.sh RUN_DIR
# Asks the run's supervisor to tear down (it stops every process and cleans up); any process
# still listed in RUN_DIR/*.pid after 5 s is stopped directly, SIGKILL as the last resort.
set -uo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bin="${OST_VENV:-$repo/.venv}/bin"
[ $# -eq 1 ] || { echo "ost_down: error: usage: ost_down.sh RUN_DIR" >&2; exit 2; }
exec "$bin/ost" up --down "$1"
