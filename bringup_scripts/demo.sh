#!/usr/bin/env bash
# The main job: set up (idempotent), generate the paper's scenario (500x200 grid, N=10 agents,
# M=20 objects, seed 1), run it over ROS 2 / DDS with one process per robot (world node + N agent
# nodes), and check the result against the in-process simulator.
#   bringup_scripts/demo.sh [--agents N] [--objects M] [--seed S] [--ci K] [--protocol ccp|hcp]
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$(bash "$repo/bringup_scripts/setup.sh" | tail -n 1)"  # stage lines on stderr, if any
agents=10 objects=20 seed=1 ci=1 protocol=ccp
while [ $# -gt 0 ]; do
  case "$1" in
    --agents|--objects|--seed|--ci|--protocol)
      [ $# -ge 2 ] || { echo "demo.sh: error: $1 needs a value" >&2; exit 2; }
      declare "${1#--}=$2"; shift 2 ;;
    -h|--help) sed -n '2,6p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "demo.sh: error: unknown argument $1 (see demo.sh --help)" >&2; exit 2 ;;
  esac
done
run_dir="$(mktemp -d "${TMPDIR:-/tmp}/ost-demo.XXXXXX")"
# ost_up.sh generates the scenario as `ost generate` does, and prints the result as `ost sim`
# does; its result file is the JSON of `ost sim --json` (one Python start less for each).
scenario="$run_dir/ros/scenario.yaml"
echo "scenario: N=$agents agents, M=$objects objects, seed $seed, 500x200 grid ($scenario)"
echo "== over DDS: 1 world node + $agents agent processes =="
bash "$repo/bringup_scripts/ost_up.sh" --agents "$agents" --objects "$objects" --seed "$seed" \
  --protocol "$protocol" --ci "$ci" --run-dir "$run_dir/ros"
"$venv/bin/ost" sim "$scenario" --protocol "$protocol" --ci "$ci" --json > "$run_dir/sim.json"
if cmp -s "$run_dir/ros/result.json" "$run_dir/sim.json"; then
  echo "== identical to the in-process simulator (ost sim --json) =="
else
  echo "== DIFFERS from ost sim --json: compare $run_dir/ros/result.json and $run_dir/sim.json ==" >&2
  exit 1
fi
echo "logs: $run_dir/ros"
