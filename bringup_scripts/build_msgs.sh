#!/usr/bin/env bash
# Build and install the ost_msgs interface package (ost_msgs_py/ost_msgs, with every protocol's
# own messages from ost_ros/protocols/<name>/msg) into a venv that holds the pinned ROS 2 Jazzy
# wheels: rosidl from the wheels, cmake and a C/C++ compiler from the machine. The venv is the ament prefix: afterwards `VENV/bin/python -c 'import ost_msgs.msg'`
# works with no environment, and `ros2 interface show ost_msgs/msg/ObjectFound` with
# AMENT_PREFIX_PATH=VENV — or after `source VENV/setup.bash`, the prefix's own setup files that
# ament writes with the build, as on a ROS install (/opt/ros/jazzy/setup.bash).
#
#   bringup_scripts/build_msgs.sh VENV
#
# Idempotent: a stamp (hash of the package's files and of the protocols' own .msg files) skips
# the build when nothing changed.
# Build tree: VENV/build/ost_msgs (never in the repository).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$(cd "${1:?usage: build_msgs.sh VENV}" && pwd)"
src="$repo/ost_msgs_py/ost_msgs"
build="$venv/build/ost_msgs"
stamp_file="$venv/share/ost_msgs/.ost-msgs-stamp"
. "$repo/bringup_scripts/stage.sh"
die() { stage_break; echo "build_msgs: error: $*" >&2; exit 2; }

# The package's files and every protocol's own .msg files (ost_ros/protocols/<name>/msg/, which
# its CMakeLists.txt gathers into it): a new or changed message anywhere rebuilds.
stamp="$(cd "$repo" && {
  ls -1 "$src/msg" "$src/action" ost_ros/protocols/*/msg/*.msg
  cat "$src/CMakeLists.txt" "$src/package.xml" "$src"/msg/*.msg "$src"/action/*.action \
    ost_ros/protocols/*/msg/*.msg
  cat bringup_scripts/build_msgs.sh
} | sha256sum | cut -d' ' -f1)"
if [ "$(cat "$stamp_file" 2>/dev/null)" = "$stamp" ] && [ -d "$venv/lib/python3.12/site-packages/ost_msgs" ]; then
  exit 0
fi

# The machine's tools: cmake, make and a C/C++ compiler. Installed as root where apt exists.
missing=()
for tool in cmake make gcc g++; do command -v "$tool" >/dev/null 2>&1 || missing+=("$tool"); done
if [ ${#missing[@]} -gt 0 ]; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    stage_begin "installing ${missing[*]} (apt-get: cmake build-essential)"
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q cmake build-essential >/dev/null 2>&1 \
      || die "apt-get install cmake build-essential failed; install ${missing[*]} by hand"
    stage_end "build tools installed (apt-get: cmake build-essential)"
  else
    die "building the ost_msgs interfaces needs ${missing[*]} (Debian/Ubuntu: apt-get install cmake build-essential)"
  fi
fi
py="$venv/bin/python3"
"$py" -c 'import sysconfig, os, sys; sys.exit(0 if os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")) else 1)' \
  || die "Python.h is missing for $py (the interpreter's development headers, e.g. python3.12-dev)"

stage_begin "building the ost_msgs interfaces (the first time one to two minutes)"
log="$venv/build_msgs.log"; : > "$log"
# A rebuild starts clean: an interface removed from the sources must not linger in the venv (its
# generated code in the build tree would be installed again, its .msg listed by the ament index).
rm -rf "$build" "$venv/share/ost_msgs/msg" "$venv/share/ost_msgs/srv" "$venv/share/ost_msgs/action" \
  "$venv/lib/python3.12/site-packages/ost_msgs"
mkdir -p "$build"
run() {  # run STEP COMMAND...: the command's output to the log, shown when it fails
  local step=$1; shift
  "$@" >>"$log" 2>&1 || { stage_break; tail -n 30 "$log" >&2; die "$step failed (full log: $log)"; }
}
# AMENT_PREFIX_PATH at configure time: rosidl finds the typesupports through the ament index.
# AMENT_CMAKE_ENVIRONMENT_GENERATION: the prefix-level setup.bash/local_setup.* of the venv.
run "cmake (configure)" env AMENT_PREFIX_PATH="$venv" cmake -S "$src" -B "$build" -DCMAKE_PREFIX_PATH="$venv" \
  -DCMAKE_INSTALL_PREFIX="$venv" -DPython3_EXECUTABLE="$py" -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=OFF \
  -DAMENT_CMAKE_ENVIRONMENT_GENERATION=ON
run "cmake --build" env AMENT_PREFIX_PATH="$venv" cmake --build "$build" -j2
run "cmake --install" cmake --install "$build"
"$py" -c 'import ost_msgs.msg' >>"$log" 2>&1 || { stage_break; tail -n 10 "$log" >&2; die "ost_msgs built but does not import (log: $log)"; }
echo "$stamp" > "$stamp_file"
stage_end "ost_msgs interfaces built"
