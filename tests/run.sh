#!/usr/bin/env bash
# The test command: sets up the venv if needed (idempotent), then runs the whole suite.
#   tests/run.sh                 # everything
#   tests/run.sh -k coordination # extra arguments go to pytest
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$(OST_SETUP_QUIET=1 bash "$repo/bringup_scripts/setup.sh" | tail -n 1)"
cd "$repo"
# DDS tests pick their own ROS_DOMAIN_ID per run; keep discovery on this host by default.
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
# UDP on loopback, not Fast DDS shared memory (see docs/ros.md, "Transport").
export FASTDDS_BUILTIN_TRANSPORTS="${FASTDDS_BUILTIN_TRANSPORTS:-UDPv4}"
exec "$venv/bin/python" -m pytest tests "$@"
