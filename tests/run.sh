#!/usr/bin/env bash
# The test command: sets up the venv if needed (idempotent), then runs the whole suite.
#   tests/run.sh                 # everything
#   tests/run.sh -k coordination # extra arguments go to pytest
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$(OST_SETUP_QUIET=1 bash "$repo/bringup_scripts/setup.sh" | tail -n 1)"
cd "$repo"
# The simulated-host tests (tests/ros/test_hosts.py) need root and nftables; as root, install the
# Debian package once if it is missing (they skip, saying why, when either is unavailable).
if [ "$(id -u)" = 0 ] && ! command -v nft >/dev/null && command -v apt-get >/dev/null; then
  echo "tests/run.sh: installing nftables for the simulated-host tests" >&2
  (apt-get install -y -q nftables >/dev/null 2>&1 \
    || { apt-get update -q >/dev/null 2>&1 && apt-get install -y -q nftables >/dev/null 2>&1; }) \
    || echo "tests/run.sh: could not install nftables; the loss and multicast-blocking tests will skip" >&2
fi
# DDS tests pick their own ROS_DOMAIN_ID per run; all DDS traffic stays on this host's loopback
# interface (bringup_scripts/dds_env.sh, docs/ros.md "Transport").
. "$repo/bringup_scripts/dds_env.sh"
exec "$venv/bin/python" -m pytest tests "$@"
