#!/usr/bin/env bash
# The test command: sets up the venv if needed (idempotent), then runs the whole suite.
#   tests/run.sh                 # everything (in-process tests on every core, then the DDS ones)
#   tests/run.sh -k coordination # extra arguments go to pytest
#   tests/run.sh -m "not dds"    # the in-process suite alone (no ROS processes)
#   OST_LINT=0 tests/run.sh ...  # skip ruff and mypy (they run first otherwise; pyproject.toml)
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# Set-up says what it does, one line per stage that had something to do (nothing when all is there).
venv="$(bash "$repo/bringup_scripts/setup.sh" | tail -n 1)"
cd "$repo"
. "$repo/bringup_scripts/stage.sh"
# The simulated-host tests (tests/ros/test_hosts.py) need root and nftables; as root, install the
# Debian package once if it is missing (they skip, saying why, when either is unavailable).
if [ "$(id -u)" = 0 ] && ! command -v nft >/dev/null && command -v apt-get >/dev/null; then
  stage_begin "installing nftables for the simulated-host tests (apt-get)"
  if (apt-get install -y -q nftables >/dev/null 2>&1 \
      || { apt-get update -q >/dev/null 2>&1 && apt-get install -y -q nftables >/dev/null 2>&1; }); then
    stage_end "nftables installed (apt-get)"
  else
    stage_break
    echo "tests/run.sh: could not install nftables; the loss and multicast-blocking tests will skip" >&2
  fi
fi
# colcon, the real ros2 CLI and launch, for tests/ros/test_colcon.py and test_ros2cli.py (test
# tooling: colcon from PyPI, the CLI from ../shared/ros2 — without those sources the CLI tests
# skip, saying why; not part of the product).
bash "$repo/tests/ros2_tools.sh" "$venv"
# Lint, format and types first (seconds): the same checks for everyone (pyproject.toml).
if [ "${OST_LINT:-1}" = 1 ]; then
  "$venv/bin/ruff" check --quiet . && "$venv/bin/ruff" format --check --quiet . && "$venv/bin/mypy" \
    || { echo "tests/run.sh: ruff or mypy found problems (above); OST_LINT=0 skips this step" >&2; exit 1; }
fi
# DDS tests pick their own ROS_DOMAIN_ID per run; all DDS traffic stays on this host's loopback
# interface (bringup_scripts/dds_env.sh, docs/ros.md "Transport").
. "$repo/bringup_scripts/dds_env.sh"
if [ $# -gt 0 ]; then
  exec "$venv/bin/python" -m pytest tests "$@"
fi
# Everything: the in-process tests on every core (pytest-xdist), then the DDS tests one at a time
# (they start processes and wait on real time: two runs at once would starve each other).
status=0
"$venv/bin/python" -m pytest tests -m "not dds" -n "$(nproc)" || status=$?
"$venv/bin/python" -m pytest tests -m dds || { s=$?; [ "$status" != 0 ] || status=$s; }
exit "$status"
