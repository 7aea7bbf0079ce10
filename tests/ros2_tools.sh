#!/usr/bin/env bash
# Test tooling, not part of the product: the tools a ROS user has, in the test venv.
#  - colcon (colcon-common-extensions, pinned in tests/ros2_tools.lock, from PyPI):
#    tests/ros/test_colcon.py builds the workspace with it as a ROS user would;
#  - the real ROS 2 Jazzy command-line tools (ros2cli, launch, launch_ros) from their unmodified
#    sources in ../shared/ros2 (a full ROS install has them; PyPI does not):
#    tests/ros/test_ros2cli.py proves the product works with them, and skips (saying why) where
#    they are absent.
#
#   bash tests/ros2_tools.sh VENV      # idempotent (stamps); ~1.5 min the first time, then silent
#
# One line per stage on stderr with the time it took (bringup_scripts/stage.sh).
# Sources: $OST_ROS2_SOURCES, else <repo>/../shared/ros2. Without them: a note, exit 0.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$(cd "${1:?usage: ros2_tools.sh VENV}" && pwd)"
src="${OST_ROS2_SOURCES:-$repo/../shared/ros2}"
py="$venv/bin/python3"
. "$repo/bringup_scripts/stage.sh"
say() { echo "ros2_tools: $*" >&2; }
log="$venv/ros2_tools.log"
fail() { stage_break; tail -n 30 "$log" >&2; say "error: $* (log: $log)"; exit 1; }

# 1. colcon, exactly the pinned set (--no-deps: what it shares with the product is
#    requirements.lock's, already installed).
lock="$repo/tests/ros2_tools.lock"
stamp="$(sha256sum < "$lock" | cut -d' ' -f1)"
if [ "$(cat "$venv/.ost-colcon-stamp" 2>/dev/null)" != "$stamp" ]; then
  stage_begin "installing colcon (tests/ros2_tools.lock)"
  : > "$log"
  "$py" -m pip install -q --disable-pip-version-check --no-deps -r "$lock" >>"$log" 2>&1 \
    || fail "pip install -r $lock failed"
  "$venv/bin/colcon" --help >/dev/null 2>>"$log" || fail "colcon --help failed"
  echo "$stamp" > "$venv/.ost-colcon-stamp"
  stage_end "colcon installed"
fi

# 2. the ros2 CLI and launch, from the sources
if [ ! -f "$src/install.sh" ]; then
  say "no ROS 2 CLI sources at $src (set OST_ROS2_SOURCES): the real-CLI tests will skip"
  exit 0
fi
src="$(cd "$src" && pwd)"
stamp="$( { cat "${BASH_SOURCE[0]}" "$src"/src/*/SOURCE; } | sha256sum | cut -d' ' -f1)"
[ "$(cat "$venv/.ost-ros2-tools-stamp" 2>/dev/null)" = "$stamp" ] && exit 0
stage_begin "installing the ros2 CLI and launch from $src"
: > "$log"

# 2a. ros2cli + rosidl_runtime_py (the sources' own installer)
bash "$src/install.sh" "$venv" >>"$log" 2>&1 || fail "ros2cli install failed"

# 2b. composition_interfaces (launch_ros imports it): .srv files, built with rosidl like ost_msgs.
#    It depends on wheel interface packages whose exported CMake targets carry the wheel
#    builder's include paths: point them at this venv's Python and numpy (idempotent).
pyinc="$("$py" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')"
npinc="$("$py" -c 'import numpy; print(numpy.get_include())')"
sed -i -e "s|/opt/python/cp312-cp312/include/python3.12|$pyinc|g" \
       -e "s|/opt/python/cp312-cp312/lib/python3.12/site-packages/numpy/_core/include|$npinc|g" \
       "$venv"/share/*/cmake/*__rosidl_generator_pyExport.cmake
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
cp -r "$src/src/rcl_interfaces/composition_interfaces" "$work/"
(
  export AMENT_PREFIX_PATH="$venv"
  cmake -S "$work/composition_interfaces" -B "$work/build" -DCMAKE_PREFIX_PATH="$venv" \
    -DCMAKE_INSTALL_PREFIX="$venv" -DPython3_EXECUTABLE="$py" -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=OFF
  cmake --build "$work/build" -j2
  cmake --install "$work/build"
) >>"$log" 2>&1 || fail "composition_interfaces build failed"

# 2c. launch, launch_xml, launch_yaml, launch_ros, ros2launch (pure Python; no deps pulled)
cp -r "$src/src/launch" "$src/src/launch_ros" "$work/"
"$py" -m pip install -q --disable-pip-version-check osrf-pycommon==2.0.2 >>"$log" 2>&1 || fail "osrf-pycommon"
"$py" -m pip install -q --disable-pip-version-check --no-deps --no-build-isolation \
  "$work/launch/launch" "$work/launch/launch_xml" "$work/launch/launch_yaml" \
  "$work/launch_ros/launch_ros" "$work/launch_ros/ros2launch" >>"$log" 2>&1 || fail "launch install failed"
AMENT_PREFIX_PATH="$venv" "$venv/bin/ros2" launch --help >/dev/null 2>>"$log" || fail "ros2 launch --help failed"
echo "$stamp" > "$venv/.ost-ros2-tools-stamp"
stage_end "ros2 CLI and launch installed"
