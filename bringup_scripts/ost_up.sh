#!/usr/bin/env bash
# Start a run over DDS: one world node and N agent nodes, one process (PID) each.
#   bringup_scripts/ost_up.sh --agents 10 --objects 20 --seed 1 [options]   (--help: every option)
# The options are `ost up`'s: one run configuration (ost_ros/runconfig.py) behind this script,
# `ost up` and launch/team.launch.py. docs/ros.md explains the run.
set -uo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bin="${OST_VENV:-$repo/.venv}/bin"
[ -x "$bin/ost" ] || { echo "ost_up: error: $bin/ost not found (run bringup_scripts/setup.sh)" >&2; exit 2; }

# 1. One Python call checks every option and prepares the run directory: the scenario, the run's
#    keys, one parameter file per node role, a free ROS_DOMAIN_ID and the DDS environment
#    (env.sh), and what to start (processes: NAME, simulated host or -, command).
case " $* " in *" -h "* | *" --help "*) exec "$bin/ost" up --help ;; esac
run_dir="$("$bin/ost" up --prepare "$@")" || exit $?

# 2. One process per line: the world node, the membership node (realtime), the watch node for
#    --record/--foxglove, and one agent node per robot with --spawn exec. Then this shell becomes
#    the supervisor (`ost up --supervise`, same PID, so the processes stay its children): it forks
#    the robots of --spawn fork (the default: their code imported once, ost_ros/commands/spawn.py)
#    and those that join later when due, waits for the files the nodes write (ready,
#    progress, result.json), names a process that dies, tears everything down on the result,
#    on Ctrl-C or on a failure, and prints the result.
start() {
  trap 'for f in "$run_dir"/*.pid; do kill "$(cat "$f")" 2>/dev/null; done; exit 130' INT TERM
  . "$run_dir/env.sh"
  while IFS=$'\t' read -r name host command; do
    eval "set -- $command"
    [ "$host" = - ] || set -- ip netns exec "$host" "$@"
    "$@" > "$run_dir/$name.log" 2>&1 < /dev/null &
    echo $! > "$run_dir/$name.pid"
  done < "$run_dir/processes"
  exec "$bin/ost" up --supervise "$run_dir"
}

if [ -f "$run_dir/background" ]; then
  # --background: the start and its supervisor detached from this terminal; return once the run
  # has started (exit 1 if it failed to); bringup_scripts/ost_down.sh RUN_DIR ends it.
  (trap '' HUP; start) > "$run_dir/ost_up.out" 2> "$run_dir/ost_up.log" < /dev/null &
  echo $! > "$run_dir/ost_up.pid"
  "$bin/ost" up --wait-started "$run_dir" $!
  code=$?
  echo "$run_dir"
  exit $code
fi
start
