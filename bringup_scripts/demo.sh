#!/usr/bin/env bash
# The main job: set up (idempotent), generate the paper's scenario (500x200, N=10 agents,
# M=20 objects, seed 1) and run the cost-balanced protocol on it.
#   bringup_scripts/demo.sh [--agents N] [--objects M] [--seed S] [--ci K]
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$(OST_SETUP_QUIET=1 bash "$repo/bringup_scripts/setup.sh" | tail -n 1)"
agents=10 objects=20 seed=1 ci=1
while [ $# -gt 0 ]; do
  case "$1" in
    --agents) agents="$2"; shift 2 ;;
    --objects) objects="$2"; shift 2 ;;
    --seed) seed="$2"; shift 2 ;;
    --ci) ci="$2"; shift 2 ;;
    -h|--help) sed -n '2,5p' "$0"; exit 0 ;;
    *) echo "demo.sh: error: unknown argument $1 (see demo.sh --help)" >&2; exit 2 ;;
  esac
done
run_dir="$(mktemp -d "${TMPDIR:-/tmp}/ost-demo.XXXXXX")"
trap 'rm -rf "$run_dir"' EXIT
"$venv/bin/ost" generate --agents "$agents" --objects "$objects" --seed "$seed" -o "$run_dir/scenario.yaml"
echo "scenario: N=$agents agents, M=$objects objects, seed $seed (500x200 grid)"
"$venv/bin/ost" sim "$run_dir/scenario.yaml" --protocol ccp --ci "$ci"
