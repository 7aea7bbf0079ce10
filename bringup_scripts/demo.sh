#!/usr/bin/env bash
# The main job: set up (idempotent), generate the paper's scenario (500x200 grid, N=10 agents,
# M=20 objects, seed 1), run it over ROS 2 / DDS with one process per robot (world node + N agent
# nodes), and check the result against the in-process simulator.
#   bringup_scripts/demo.sh [--agents N] [--objects M] [--seed S] [--ci K] [--protocol NAME]
#   bringup_scripts/demo.sh --realtime [--rtf R]   # no barrier: every object delivered, 0 disagreements,
#                                                 # the makespan against ost sim's
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$(bash "$repo/bringup_scripts/setup.sh" | tail -n 1)"  # stage lines on stderr, if any
agents=10 objects=20 seed=1 ci=1 protocol=ccp realtime=() rtf=""
while [ $# -gt 0 ]; do
  case "$1" in
    --agents|--objects|--seed|--ci|--protocol|--rtf)
      [ $# -ge 2 ] || { echo "demo.sh: error: $1 needs a value" >&2; exit 2; }
      declare "${1#--}=$2"; shift 2 ;;
    --realtime) realtime=(--realtime); shift ;;
    -h|--help) sed -n '2,8p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "demo.sh: error: unknown argument $1 (see demo.sh --help)" >&2; exit 2 ;;
  esac
done
run_dir="$(mktemp -d "${TMPDIR:-/tmp}/ost-demo.XXXXXX")"
# ost_up.sh generates the scenario as `ost generate` does, and prints the result as `ost sim`
# does; its result file is the JSON of `ost sim --json` (one Python start less for each).
scenario="$run_dir/ros/scenario.yaml"
echo "scenario: N=$agents agents, M=$objects objects, seed $seed, 500x200 grid ($scenario)"
[ -z "$rtf" ] || [ ${#realtime[@]} -gt 0 ] || { echo "demo.sh: error: --rtf needs --realtime" >&2; exit 2; }
[ -z "$rtf" ] || realtime+=(--rtf "$rtf")
echo "== over DDS: 1 world node + $agents agent processes${realtime:+ (realtime, no barrier)} =="
bash "$repo/bringup_scripts/ost_up.sh" --agents "$agents" --objects "$objects" --seed "$seed" \
  --protocol "$protocol" --ci "$ci" --run-dir "$run_dir/ros" "${realtime[@]}"
"$venv/bin/ost" sim "$scenario" --protocol "$protocol" --ci "$ci" --json > "$run_dir/sim.json"
if [ ${#realtime[@]} -gt 0 ]; then
  # Real time: the promise is the protocol's (every object by its n_i robots, the same schedule
  # on every robot), not byte equality with the lockstep simulator; the makespan says what the
  # network and the pace cost.
  "$venv/bin/python" - "$run_dir/ros/result.json" "$run_dir/sim.json" <<'PY' || exit 1
import json, sys
rt, sim = (json.load(open(p)) for p in sys.argv[1:3])
ok = rt["completed"] and rt["disagreements"] == 0 and rt["agreement"]
delivered = sum(o["delivered"] is not None for o in rt["objects"])
print(f"== realtime at rtf {rt['rtf']:g}: {delivered}/{len(rt['objects'])} objects delivered, "
      f"{rt['disagreements']} disagreements in {rt['coordinations_compared']} coordinations; makespan "
      f"{rt['makespan']:g} against ost sim's {sim['makespan']} ({100 * (rt['makespan'] / sim['makespan'] - 1):+.1f} %), "
      f"largest lag {max(rt['lag'].values()):.1f} steps ==")
sys.exit(0 if ok else 1)
PY
  echo "logs: $run_dir/ros"
  exit 0
fi
if cmp -s "$run_dir/ros/result.json" "$run_dir/sim.json"; then
  echo "== identical to the in-process simulator (ost sim --json) =="
else
  echo "== DIFFERS from ost sim --json: compare $run_dir/ros/result.json and $run_dir/sim.json ==" >&2
  exit 1
fi
echo "logs: $run_dir/ros"
