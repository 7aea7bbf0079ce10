#!/usr/bin/env bash
# The test command: sets up the venv if needed (idempotent), then runs the whole suite.
#   tests/run.sh                 # everything
#   tests/run.sh -k coordination # extra arguments go to pytest
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$(OST_SETUP_QUIET=1 bash "$repo/bringup_scripts/setup.sh" | tail -n 1)"
cd "$repo"
# DDS tests pick their own ROS_DOMAIN_ID per run; all DDS traffic stays on this host's loopback
# interface (bringup_scripts/dds_env.sh, docs/ros.md "Transport").
. "$repo/bringup_scripts/dds_env.sh"
exec "$venv/bin/python" -m pytest tests "$@"
