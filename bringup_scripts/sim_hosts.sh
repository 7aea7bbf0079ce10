#!/usr/bin/env bash
# Simulated hosts on one machine (network namespaces on one bridge; root): ost_ros/commands/hosts.py.
#   bringup_scripts/sim_hosts.sh up NAME K [--net N] [--loss PCT] [--block-multicast]
#   bringup_scripts/sim_hosts.sh down NAME
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
exec "${OST_VENV:-$repo/.venv}/bin/python" -m ost_ros.commands.hosts "$@"
