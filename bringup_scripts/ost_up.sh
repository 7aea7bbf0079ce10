#!/usr/bin/env bash
# Start a run over DDS: one world node and N agent nodes, one process (PID) each.
# `ost_up.sh --help` prints the usage; docs/ros.md explains the run.
set -uo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="${OST_VENV:-$repo/.venv}"
bin="$venv/bin"
me="ost_up"

die() { echo "$me: error: $*" >&2; exit 2; }
usage() {
  cat <<'USAGE'
usage: ost_up.sh --agents N (--objects M --seed S | --scenario FILE) [options]

Start a run over DDS: one world node and N agent nodes, one process each. Waits for discovery
(counted, not slept), waits for the result, prints it and tears everything down (also on Ctrl-C
or when a process dies, naming it). Logs, PIDs and result.json go to the run directory.

scenario:
  --agents N                 team size (with --scenario: replaces the file's team)
  --objects M --seed S       generate the paper's random scenario
  --width W --height H --nmax X   its grid and largest group (defaults: ost generate's)
  --scenario FILE            a scenario YAML (ost generate)
  --partition equal|negotiated    search areas: equal, or negotiated first (by speed, zones)
protocol:
  --protocol NAME            a registered protocol (ost protocols list; default ccp)
  --ci K | --interval T      coordination trigger (default --ci 1)
  --coordination distributed|coordinator
  --planner paper|improved   CCP: Algorithm Coordination as published, or the improved planner
  --no-skip                  no event skipping: every step is a round trip
  --max-steps S              step limit (default: the simulator's)
ROS:
  --namespace NS             the run's namespace (default ost: /ost/world, /ost/object_found, ...);
                             two teams in two namespaces share a domain without interfering
  --domain-id D              ROS_DOMAIN_ID (default: a free one in 10..99)
  --executor events|single   how the nodes wait for samples (default events: rclpy's
                             EventsExecutor; single: SingleThreadedExecutor)
  --insecure                 no signed messages (default: every message is signed with keys
                             made for the run in DIR/keys; receivers drop the rest)
watch:
  --record FILE.mcap         record every topic of the run (rosbag2-style MCAP; ost record info,
                             ost replay FILE --animate out.gif)
  --foxglove [PORT]          live view: a Foxglove WebSocket server on ws://127.0.0.1:PORT
                             (default 8765) streaming robots, objects and states
  (on a terminal a progress line shows the step and the objects delivered)
run:
  --run-dir DIR              logs, PIDs, result.json (default: a new /tmp/ost_run.XXXXXX)
  --json                     print the result as `ost sim --json` does
  --background               return once the run has started (exit 1 if it failed to start);
                             the world stays up with the result on <ns>/result until
                             `bringup_scripts/ost_down.sh DIR`
  --timeout SEC              stop a run without a result after SEC seconds
faults:
  --kill-agent AGENT:STEP    that agent's process SIGKILLs itself at that step (repeatable)
  --failure-timeout SEC      liveliness lease: a silent agent fails after 2 x SEC (default 1)
  --mute-negotiation AGENT:STEP   that NCP negotiator stops answering from that step
  --respawn-world K          restart a dead world node from its checkpoint (K times)
  --hosts K [--loss PCT] [--discovery multicast|static|server]
                             (root) spread the processes over K simulated hosts
USAGE
}
say() { echo "$me: $*" >&2; }

agents="" objects="" seed="" scenario="" protocol="ccp" ci="1" interval="" width="" height="" nmax=""
mute="" respawn=0 hosts=0 loss=0 discovery="multicast" kills=() failure_timeout=1.0 partition=equal coordination=distributed
record="" foxglove=0 insecure=0 planner=paper executor=events
domain="${ROS_DOMAIN_ID:-}" run_dir="" json=0 skip=true max_steps=0 timeout=0 background=0 stay=0 ns="ost"
need() { [ $# -ge 2 ] && [ -n "$2" ] || die "$1 needs a value"; }
int() { [[ "$2" =~ ^[0-9]+$ ]] || die "$1: expected a non-negative integer, got '$2'"; }
while [ $# -gt 0 ]; do
  case "$1" in
    --agents) need "$@"; int "$1" "$2"; agents="$2"; shift 2 ;;
    --objects) need "$@"; int "$1" "$2"; objects="$2"; shift 2 ;;
    --seed) need "$@"; int "$1" "$2"; seed="$2"; shift 2 ;;
    --scenario) need "$@"; scenario="$2"; shift 2 ;;
    --protocol) need "$@"; protocol="$2"; shift 2 ;;
    --ci) need "$@"; int "$1" "$2"; ci="$2"; shift 2 ;;
    --interval) need "$@"; int "$1" "$2"; interval="$2"; shift 2 ;;
    --width) need "$@"; int "$1" "$2"; width="$2"; shift 2 ;;
    --height) need "$@"; int "$1" "$2"; height="$2"; shift 2 ;;
    --nmax) need "$@"; int "$1" "$2"; nmax="$2"; shift 2 ;;
    --domain-id) need "$@"; int "$1" "$2"; domain="$2"; shift 2 ;;
    --run-dir) need "$@"; run_dir="$2"; shift 2 ;;
    --max-steps) need "$@"; int "$1" "$2"; max_steps="$2"; shift 2 ;;
    --timeout) need "$@"; int "$1" "$2"; timeout="$2"; shift 2 ;;
    --mute-negotiation) need "$@"; [[ "$2" =~ ^[0-9]+:[0-9]+$ ]] \
        || die "--mute-negotiation: expected AGENT:STEP, got '$2'"; mute="$2"; shift 2 ;;
    --respawn-world) need "$@"; int "$1" "$2"; respawn="$2"; shift 2 ;;
    --coordination) need "$@"; case "$2" in distributed|coordinator) ;; *)
        die "--coordination: '$2' is not distributed or coordinator" ;; esac; coordination="$2"; shift 2 ;;
    --planner) need "$@"; case "$2" in paper|improved) ;; *)
        die "--planner: '$2' is not paper or improved" ;; esac; planner="$2"; shift 2 ;;
    --partition) need "$@"; case "$2" in equal|negotiated) ;; *)
        die "--partition: '$2' is not equal or negotiated" ;; esac; partition="$2"; shift 2 ;;
    --kill-agent) need "$@"; [[ "$2" =~ ^[0-9]+:[0-9]+$ ]] \
        || die "--kill-agent: expected AGENT:STEP, got '$2'"; kills+=("$2"); shift 2 ;;
    --failure-timeout) need "$@"; [[ "$2" =~ ^[0-9]+(\.[0-9]+)?$ ]] \
        || die "--failure-timeout: expected seconds (a number), got '$2'"; failure_timeout="$2"
      [[ "$2" == *.* ]] || failure_timeout="$2.0"; shift 2 ;;   # a float parameter
    --hosts) need "$@"; int "$1" "$2"; hosts="$2"; shift 2 ;;
    --loss) need "$@"; int "$1" "$2"; loss="$2"; shift 2 ;;
    --discovery) need "$@"; discovery="$2"; shift 2 ;;
    --record) need "$@"; case "$2" in *.mcap) ;; *) die "--record: '$2' must end in .mcap" ;; esac
      record="$2"; shift 2 ;;
    --foxglove) if [ $# -ge 2 ] && [[ "$2" =~ ^[0-9]+$ ]]; then foxglove="$2"; shift 2; else foxglove=8765; shift; fi
      [ "$foxglove" -ge 1 ] && [ "$foxglove" -le 65535 ] || die "--foxglove: port $foxglove is not in 1..65535" ;;
    --json) json=1; shift ;;
    --insecure) insecure=1; shift ;;
    --executor) need "$@"; case "$2" in events|single) ;; *)
        die "--executor: '$2' is not events or single" ;; esac; executor="$2"; shift 2 ;;
    --no-skip) skip=false; shift ;;
    --background) background=1; shift ;;
    --stay) stay=1; shift ;;   # (internal: --background's supervisor) keep the world up after the run
    --namespace) need "$@"; [[ "$2" =~ ^/?[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*$ ]] \
        || die "--namespace: '$2' is not a ROS namespace (letters, digits, _ and /)"; ns="${2#/}"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) die "unknown argument '$1' (see --help)" ;;
  esac
done
[ -x "$bin/world_node" ] || die "$bin/world_node not found (run bringup_scripts/setup.sh)"
if [ -n "$scenario" ]; then
  [ -z "$objects$seed" ] || die "--scenario excludes --objects/--seed"
  [ -f "$scenario" ] || die "--scenario: $scenario: no such file"
else
  [ -n "$agents" ] && [ -n "$objects" ] && [ -n "$seed" ] \
    || die "give --agents N --objects M --seed S, or --scenario FILE"
fi
[ -z "$agents" ] || [ "$agents" -ge 1 ] || die "--agents: must be at least 1"
[ "$ci" -ge 1 ] || die "--ci: must be at least 1"
if [ -n "$record" ]; then
  [ -d "$(dirname "$record")" ] || die "--record: no such directory $(dirname "$record")"
  record="$(cd "$(dirname "$record")" && pwd)/$(basename "$record")"
fi
[ -z "$domain" ] || [ "$domain" -le 232 ] || die "--domain-id: $domain is above 232"
# What the protocol can run, from the registry (one line and exit code 2 if it cannot); checked
# here when a background run forks, else with the rest of the preparation (world_node.prepare).
check=(--protocol "$protocol" --coordination "$coordination"); [ -z "$mute" ] || check+=(--silence)
[ "$partition" = negotiated ] && check+=(--own-sweeps)
prepare() { "$bin/python" -m world_node.prepare "${check[@]}" "$@"; }
case "$discovery" in multicast|static|server) ;; *) die "--discovery: '$discovery' is not multicast, static or server" ;; esac
[ "$loss" -le 100 ] || die "--loss: a percentage 0..100"
if [ "$hosts" -gt 0 ]; then
  [ "$(id -u)" = 0 ] || die "--hosts: simulated hosts need root (network namespaces)"
else
  [ "$loss" = 0 ] && [ "$discovery" = multicast ] || die "--loss and --discovery need --hosts K"
fi

# ------------------------------------------------------------------ run directory, background
made_run_dir=0
unmade() { [ "$made_run_dir" = 0 ] || rm -rf "$run_dir"; exit "$1"; }   # a run that never started
if [ -z "$run_dir" ]; then
  run_dir="$(mktemp -d /tmp/ost_run.XXXXXX)" || die "cannot create a run directory"
  made_run_dir=1
else
  mkdir -p "$run_dir" || die "--run-dir: cannot create $run_dir"
  [ ! -f "$run_dir/world.pid" ] || die "--run-dir: $run_dir holds a run (ost_down.sh it first)"
fi
run_dir="$(cd "$run_dir" && pwd)"
if [ "$background" = 1 ]; then
  prepare || unmade 2
  args=()
  for a in "$@"; do args+=("$a"); done
  # Re-run this script in the background with the same options, supervising the run.
  fwd=(--run-dir "$run_dir" --protocol "$protocol" --ci "$ci" --max-steps "$max_steps" --timeout "$timeout"
       --namespace "$ns" --planner "$planner" --executor "$executor" --stay)
  [ -n "$agents" ] && fwd+=(--agents "$agents")
  [ -n "$scenario" ] && fwd+=(--scenario "$scenario")
  [ -n "$objects" ] && fwd+=(--objects "$objects" --seed "$seed")
  [ -n "$interval" ] && fwd+=(--interval "$interval")
  [ -n "$width" ] && fwd+=(--width "$width")
  [ -n "$height" ] && fwd+=(--height "$height")
  [ -n "$nmax" ] && fwd+=(--nmax "$nmax")
  [ -n "$mute" ] && fwd+=(--mute-negotiation "$mute")
  [ "$respawn" -gt 0 ] && fwd+=(--respawn-world "$respawn")
  for kv in "${kills[@]}"; do fwd+=(--kill-agent "$kv"); done
  fwd+=(--failure-timeout "$failure_timeout" --partition "$partition" --coordination "$coordination")
  [ "$hosts" -gt 0 ] && fwd+=(--hosts "$hosts" --loss "$loss" --discovery "$discovery")
  [ -n "$domain" ] && fwd+=(--domain-id "$domain")
  [ "$skip" = false ] && fwd+=(--no-skip)
  [ "$json" = 1 ] && fwd+=(--json)
  [ "$insecure" = 1 ] && fwd+=(--insecure)
  [ -n "$record" ] && fwd+=(--record "$record")
  [ "$foxglove" -gt 0 ] && fwd+=(--foxglove "$foxglove")
  nohup "$0" "${fwd[@]}" > "$run_dir/ost_up.out" 2> "$run_dir/ost_up.log" < /dev/null &
  sup=$!
  echo $sup > "$run_dir/ost_up.pid"
  # Until the world has started stepping (every agent matched), or the supervisor gave up.
  started=0
  for _ in $(seq 1 1200); do
    grep -q "discovery complete" "$run_dir/ost_up.log" 2>/dev/null && { started=1; break; }
    kill -0 "$sup" 2>/dev/null || break
    sleep 0.1
  done
  cat "$run_dir/ost_up.log" >&2
  echo "$run_dir"
  if [ "$started" = 0 ]; then
    if kill -0 "$sup" 2>/dev/null; then
      say "the run did not start within 120 s; stopping it"
      bash "$repo/bringup_scripts/ost_down.sh" "$run_dir" >/dev/null 2>&1
    else
      say "the run failed to start (see $run_dir/ost_up.log)"
    fi
    exit 1
  fi
  exit 0
fi

# ------------------------------------------------------------------ scenario and parameters
# One Python process checks the protocol, generates the scenario if asked, reads the team's ids
# and makes the run's keys (world_node/prepare.py: each Python start costs ~0.4 s).
prep=()
if [ -z "$scenario" ]; then
  prep+=(--generate "$run_dir/scenario.yaml" --agents "$agents" --objects "$objects" --seed "$seed")
  [ -n "$width" ] && prep+=(--width "$width")
  [ -n "$height" ] && prep+=(--height "$height")
  [ -n "$nmax" ] && prep+=(--nmax "$nmax")
  scenario="$run_dir/scenario.yaml"
  team=0
else
  scenario="$(cd "$(dirname "$scenario")" && pwd)/$(basename "$scenario")"
  team="${agents:-0}"
  prep+=(--scenario "$scenario" --team "$team")
fi
if [ "$partition" = negotiated ]; then
  [ "$team" = 0 ] || die "--partition negotiated: --agents would replace the scenario's team; give a scenario with it"
  if [ "${prep[0]}" = --generate ]; then prepare "${prep[@]}" > /dev/null || unmade 2; fi
  "$bin/ost" negotiate partition --scenario "$scenario" -o "$run_dir/scenario_negotiated.yaml" \
    > "$run_dir/partition.txt" || exit 2
  scenario="$run_dir/scenario_negotiated.yaml"
  say "search areas negotiated: $(tail -n 1 "$run_dir/partition.txt")"
  prep=(--scenario "$scenario" --team 0)
fi
# Signed messages: a key per robot and one for the world, made for this run (docs/ros.md).
if [ "$insecure" = 1 ]; then
  auth_params="    insecure: true"
else
  rm -rf "$run_dir/keys"
  prep+=(--keys "$run_dir/keys")
  auth_params="    keys: \"$run_dir/keys\""
fi
ids="$(prepare "${prep[@]}")" || unmade 2
n="$(echo $ids | wc -w)"

# ------------------------------------------------------------------ domain and discovery range
lock_root="/tmp/ost_domain_locks"
mkdir -p "$lock_root"
domain_lock=""
if [ -z "$domain" ]; then
  # A free domain id: take a lock directory (atomic mkdir); stale locks of dead runs are reused.
  start=$(( (RANDOM % 90) + 10 ))
  for k in $(seq 0 89); do
    d=$(( (start + k) % 90 + 10 ))
    if mkdir "$lock_root/$d" 2>/dev/null; then domain="$d"; break; fi
    owner="$(cat "$lock_root/$d/pid" 2>/dev/null)"
    if [ -n "$owner" ] && ! kill -0 "$owner" 2>/dev/null; then
      rm -rf "$lock_root/$d"; mkdir "$lock_root/$d" 2>/dev/null && { domain="$d"; break; }
    fi
  done
  [ -n "$domain" ] || die "no free ROS_DOMAIN_ID in 10..99 (set --domain-id)"
  echo $$ > "$lock_root/$domain/pid"
  domain_lock="$lock_root/$domain"
fi
export ROS_DOMAIN_ID="$domain"
# Host-only traffic, UDP on loopback (bringup_scripts/dds_env.sh, docs/ros.md "Transport").
. "$repo/bringup_scripts/dds_env.sh"
netns=""
if [ "$hosts" -gt 0 ]; then
  netns="ost$domain"
  block=(); [ "$discovery" = multicast ] || block=(--block-multicast)
  ips=($(bash "$repo/bringup_scripts/sim_hosts.sh" up "$netns" "$hosts" --net "$domain" --loss "$loss" "${block[@]}")) \
    || die "--hosts: could not create the simulated hosts"
  export FASTRTPS_DEFAULT_PROFILES_FILE="$repo/bringup_scripts/fastdds_hosts_udp.xml"
  export ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET
  unset ROS_STATIC_PEERS ROS_DISCOVERY_SERVER
  if [ "$discovery" = static ]; then
    export ROS_STATIC_PEERS="$(IFS=';'; echo "${ips[*]}")"
  elif [ "$discovery" = server ]; then
    export ROS_DISCOVERY_SERVER="${ips[0]}:11811"
  fi
  host_of() { echo "${netns}_h$(( $1 % hosts ))"; }
fi

observers=0   # a recorder / live view: the run starts once every writer has matched it too
{ [ -n "$record" ] || [ "$foxglove" -gt 0 ]; } && observers=1
cat > "$run_dir/params.yaml" <<EOF
/**:
  ros__parameters:
    scenario: "$scenario"
    agents: $team
    protocol: "$protocol"
    ci: $ci
    interval: ${interval:-0}
    coordination: "$coordination"
    planner: "$planner"
    failure_timeout: $failure_timeout
    observers: $observers
    executor: "$executor"
$auth_params
EOF
cat > "$run_dir/world_params.yaml" <<EOF
/**:
  ros__parameters:
    scenario: "$scenario"
    agents: $team
    result_file: "$run_dir/result.json"
    checkpoint_file: "$([ "$respawn" -gt 0 ] && echo "$run_dir/world.checkpoint")"
    event_skipping: $skip
    max_steps: $max_steps
    failure_timeout: $failure_timeout
    exit_when_done: $([ "$stay" = 1 ] && echo false || echo true)
    observers: $observers
    progress_file: "$run_dir/progress"
    executor: "$executor"
$auth_params
EOF

# ------------------------------------------------------------------ processes and teardown
shm_before="$(ls /dev/shm 2>/dev/null | sort)"
declare -A names
pids=()
teardown() {
  trap - INT TERM
  for p in "${pids[@]}"; do kill -TERM "$p" 2>/dev/null; done
  for _ in $(seq 1 30); do   # up to 3 s for a clean exit (destroy_node), then SIGKILL
    alive=0
    for p in "${pids[@]}"; do kill -0 "$p" 2>/dev/null && alive=1; done
    [ "$alive" = 0 ] && break
    sleep 0.1
  done
  for p in "${pids[@]}"; do kill -KILL "$p" 2>/dev/null; done
  wait 2>/dev/null
  # Fast DDS shared-memory files that appeared during the run and no process maps any more.
  for f in $(comm -13 <(echo "$shm_before") <(ls /dev/shm 2>/dev/null | sort)); do
    case "$f" in fastrtps_*|sem.fastrtps_*|fast_datasharing*) ;; *) continue ;; esac
    grep -qs "/dev/shm/$f" /proc/[0-9]*/maps || rm -f "/dev/shm/$f"
  done
  rm -f "$run_dir"/*.pid
  [ -n "$netns" ] && bash "$repo/bringup_scripts/sim_hosts.sh" down "$netns"
  [ -n "$domain_lock" ] && rm -rf "$domain_lock"
}
on_signal() { say "interrupted: stopping ${#pids[@]} processes"; teardown; exit 130; }
trap on_signal INT TERM

t0=${EPOCHREALTIME//[!0-9]/}   # microseconds; read without forking (the loop below polls every 0.1 s)
elapsed_ms() { echo $(( (${EPOCHREALTIME//[!0-9]/} - t0) / 1000 )); }
launch() {   # launch HOST_INDEX COMMAND... &: on that simulated host if any; exec keeps $! the
  local h="$1"; shift   # process's own PID (ip netns exec execs too)
  if [ -n "$netns" ]; then exec ip netns exec "$(host_of "$h")" "$@"; else exec "$@"; fi
}
if [ "$discovery" = server ]; then
  # the wheel's binary finds Fast DDS in the venv's lib/, its bundled libraries beside the wheel
  fastlibs="$(ls -d "$venv"/lib/python3*/site-packages/ros_fastrtps.libs 2>/dev/null | head -n 1)"
  launch 0 env LD_LIBRARY_PATH="$venv/lib:$fastlibs${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" \
    "$bin/fast-discovery-server" -i 0 -l "${ips[0]}" -p 11811 > "$run_dir/discovery_server.log" 2>&1 &
  pids+=($!); names[$!]="discovery_server"; echo $! > "$run_dir/discovery_server.pid"
fi
nsarg=(-r "__ns:=/$ns")
watch_pid=""
if [ "$observers" -gt 0 ]; then
  wargs=(-p "exit_when_done:=$([ "$stay" = 1 ] && echo false || echo true)")
  [ -n "$record" ] && wargs+=(-p "record:=$record")
  [ "$foxglove" -gt 0 ] && wargs+=(-p "foxglove_port:=$foxglove")
  launch 0 "$bin/watch_node" --ros-args "${nsarg[@]}" "${wargs[@]}" > "$run_dir/watch.log" 2>&1 &
  watch_pid=$!; pids+=($watch_pid); names[$watch_pid]="watch"; echo $watch_pid > "$run_dir/watch.pid"
  [ -n "$record" ] && say "recording every topic of /$ns to $record"
  [ "$foxglove" -gt 0 ] && say "live view: open ws://127.0.0.1:$foxglove in the Foxglove app (Open connection, Foxglove WebSocket)"
fi
launch 0 "$bin/world_node" --ros-args --params-file "$run_dir/world_params.yaml" "${nsarg[@]}" > "$run_dir/world.log" 2>&1 &
world_pid=$!; pids+=($world_pid); names[$world_pid]="world"; echo $world_pid > "$run_dir/world.pid"
slot=0
for i in $ids; do
  slot=$(( slot + 1 ))
  extra=()   # fault injection: this agent's negotiator goes silent from a step on
  [ -n "$mute" ] && [ "${mute%%:*}" = "$i" ] && extra=(-p "mute_negotiation_from:=${mute##*:}")
  for kv in "${kills[@]}"; do   # fault injection: this agent's process dies at a step
    [ "${kv%%:*}" = "$i" ] && extra+=(-p "die_at_step:=${kv##*:}")
  done
  launch "$slot" "$bin/agent_node" --ros-args --params-file "$run_dir/params.yaml" -p "agent_id:=$i" "${extra[@]}" "${nsarg[@]}" \
    > "$run_dir/agent_$i.log" 2>&1 &
  pids+=($!); names[$!]="agent_$i"; echo $! > "$run_dir/agent_$i.pid"
done
if [ -n "$netns" ]; then
  say "started world + $n agents on $hosts simulated hosts (${ips[*]}; loss $loss %, discovery $discovery; ROS_DOMAIN_ID=$ROS_DOMAIN_ID, run dir $run_dir)"
else
  say "started world + $n agents (ROS_DOMAIN_ID=$ROS_DOMAIN_ID, namespace /$ns, run dir $run_dir)"
fi

shown=""
show_progress() {   # a progress line on a terminal (quiet otherwise): step, objects delivered
  [ -t 2 ] && [ "$stay" = 0 ] || return 0
  local line; line="$(cat "$run_dir/progress" 2>/dev/null)" || return 0
  [ -n "$line" ] && [ "$line" != "$shown" ] || return 0
  shown="$line"; set -- $line
  printf '\r\033[K%s: step %s, delivered %s/%s' "$me" "$1" "$2" "$3" >&2
}
end_progress() { [ -z "$shown" ] || printf '\r\033[K' >&2; shown=""; }
started=0
while :; do
  if [ "$started" = 0 ] && grep -q "agents ready; step 0" "$run_dir/world.log" 2>/dev/null; then
    started=1
    say "discovery complete: $n agents matched after $(elapsed_ms) ms"
  fi
  show_progress
  if [ -f "$run_dir/result.json" ] && { [ "$stay" = 1 ] || ! kill -0 "$world_pid" 2>/dev/null; }; then
    break
  fi
  for k in "${!pids[@]}"; do
    p="${pids[$k]}"
    if ! kill -0 "$p" 2>/dev/null; then
      wait "$p" 2>/dev/null; rc=$?
      if [ "${names[$p]}" = world ] && [ ! -f "$run_dir/result.json" ] && [ "$respawn" -gt 0 ]; then
        respawn=$(( respawn - 1 ))
        say "world (pid $p) died with exit code $rc; restarting it from its checkpoint ($respawn restarts left)"
        launch 0 "$bin/world_node" --ros-args --params-file "$run_dir/world_params.yaml" "${nsarg[@]}" -p resume:=true \
          >> "$run_dir/world.log" 2>&1 &
        world_pid=$!; pids[$k]=$world_pid; names[$world_pid]="world"; echo $world_pid > "$run_dir/world.pid"
        continue
      fi
      if [ -f "$run_dir/result.json" ]; then   # the run is over: everyone leaves
        unset 'pids[k]'; continue
      fi
      if [[ "${names[$p]}" == agent_* ]] && grep -q "agents ready; step 0" "$run_dir/world.log" 2>/dev/null; then
        say "${names[$p]} (pid $p) died mid-run (exit code $rc); the world declares it failed after" \
            "2 x ${failure_timeout} s without its liveliness"
        unset 'pids[k]'; continue
      fi
      if [ "$rc" != 0 ] || [ ! -f "$run_dir/result.json" ]; then
        end_progress
        say "${names[$p]} (pid $p) died with exit code $rc before the result; see $run_dir/${names[$p]}.log"
        tail -n 3 "$run_dir/${names[$p]}.log" >&2
        teardown; exit 1
      fi
    fi
  done
  if [ "$timeout" -gt 0 ] && [ $(( ${EPOCHREALTIME//[!0-9]/} - t0 )) -gt $(( timeout * 1000000 )) ]; then
    say "timeout: no result after $timeout s; stopping"
    teardown; exit 1
  fi
  sleep 0.1
done
end_progress
if [ -n "$watch_pid" ] && [ "$stay" = 0 ]; then
  # The recorder closes its file a moment after the result (samples still on their way).
  for _ in $(seq 1 100); do kill -0 "$watch_pid" 2>/dev/null || break; sleep 0.1; done
  [ -z "$record" ] || say "recorded $record: $(grep -o 'recorded [0-9]* messages on [0-9]* topics' "$run_dir/watch.log" | head -n 1)"
fi
[ "$stay" = 1 ] || teardown
if [ "$json" = 1 ]; then
  "$bin/python" -m world_node.report "$run_dir/result.json" --json
else
  "$bin/python" -m world_node.report "$run_dir/result.json"
  say "logs and result in $run_dir"
fi
if [ "$stay" = 1 ]; then   # --background: the result stays on <ns>/result until ost_down.sh
  say "run over; the world stays up with the result on /$ns/result until: bringup_scripts/ost_down.sh $run_dir"
  while kill -0 "$world_pid" 2>/dev/null; do sleep 0.5; done
  teardown
fi
