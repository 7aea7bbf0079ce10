#!/usr/bin/env bash
# Test tooling, not part of the product: the real ROS 2 Jazzy command-line tools (ros2cli, launch,
# launch_ros) into the test venv, from their unmodified sources in ../shared/ros2 (a full ROS
# install has them; PyPI does not). tests/ros/test_ros2cli.py uses them to prove the product
# works with the tools a ROS user has, and skips (saying why) where they are absent.
#
#   bash tests/ros2_tools.sh VENV      # idempotent (stamp); ~1 min the first time
#
# Sources: $OST_ROS2_SOURCES, else <repo>/../shared/ros2. Without them: a note, exit 0.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$(cd "${1:?usage: ros2_tools.sh VENV}" && pwd)"
src="${OST_ROS2_SOURCES:-$repo/../shared/ros2}"
say() { echo "ros2_tools: $*" >&2; }
if [ ! -f "$src/install.sh" ]; then
  say "no ROS 2 CLI sources at $src (set OST_ROS2_SOURCES): the real-CLI tests will skip"
  exit 0
fi
src="$(cd "$src" && pwd)"
stamp="$( { cat "${BASH_SOURCE[0]}" "$src"/src/*/SOURCE; } | sha256sum | cut -d' ' -f1)"
[ "$(cat "$venv/.ost-ros2-tools-stamp" 2>/dev/null)" = "$stamp" ] && exit 0
t0=$(date +%s)
log="$venv/ros2_tools.log"; : > "$log"
fail() { tail -n 30 "$log" >&2; say "error: $* (log: $log)"; exit 1; }

# 1. ros2cli + rosidl_runtime_py (the sources' own installer)
bash "$src/install.sh" "$venv" >>"$log" 2>&1 || fail "ros2cli install failed"

# 2. composition_interfaces (launch_ros imports it): .srv files, built with rosidl like ost_msgs.
#    It depends on wheel interface packages whose exported CMake targets carry the wheel
#    builder's include paths: point them at this venv's Python and numpy (idempotent).
py="$venv/bin/python3"
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

# 3. launch, launch_xml, launch_yaml, launch_ros, ros2launch (pure Python; no deps pulled)
cp -r "$src/src/launch" "$src/src/launch_ros" "$work/"
"$py" -m pip install -q --disable-pip-version-check osrf-pycommon==2.0.2 >>"$log" 2>&1 || fail "osrf-pycommon"
"$py" -m pip install -q --disable-pip-version-check --no-deps --no-build-isolation \
  "$work/launch/launch" "$work/launch/launch_xml" "$work/launch/launch_yaml" \
  "$work/launch_ros/launch_ros" "$work/launch_ros/ros2launch" >>"$log" 2>&1 || fail "launch install failed"
AMENT_PREFIX_PATH="$venv" "$venv/bin/ros2" launch --help >/dev/null 2>>"$log" || fail "ros2 launch --help failed"
echo "$stamp" > "$venv/.ost-ros2-tools-stamp"
say "ros2 CLI and launch installed in $(( $(date +%s) - t0 )) s"
