#!/usr/bin/env bash
# Stop a run started with `ost_up.sh --background`:  bringup_scripts/ost_down.sh RUN_DIR
# Asks the supervising ost_up.sh to tear down (it stops every process and cleans up); any
# process still listed in RUN_DIR/*.pid after 5 s is stopped here, SIGKILL as the last resort.
set -uo pipefail
die() { echo "ost_down: error: $*" >&2; exit 2; }
[ $# -eq 1 ] || die "usage: ost_down.sh RUN_DIR"
run_dir="$1"
[ -d "$run_dir" ] || die "$run_dir: no such run directory"
sup="$(cat "$run_dir/ost_up.pid" 2>/dev/null)"
if [ -n "$sup" ] && kill -0 "$sup" 2>/dev/null; then
  kill -TERM "$sup"
  for _ in $(seq 1 50); do kill -0 "$sup" 2>/dev/null || break; sleep 0.1; done
fi
left=0
for f in "$run_dir"/*.pid; do
  [ -f "$f" ] || continue
  [ "$(basename "$f")" = ost_up.pid ] && { rm -f "$f"; continue; }
  p="$(cat "$f")"
  if kill -0 "$p" 2>/dev/null; then
    left=$((left + 1)); kill -TERM "$p" 2>/dev/null
    for _ in $(seq 1 30); do kill -0 "$p" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$p" 2>/dev/null
  fi
  rm -f "$f"
done
extra=""; [ "$left" -gt 0 ] && extra=" ($left processes stopped directly)"
echo "ost_down: stopped the run in $run_dir$extra" >&2
