#!/usr/bin/env bash
# Idempotent bootstrap: a CPython 3.12 venv with the pinned ROS 2 Jazzy wheels and this project,
# the ost_msgs interfaces built into it (bringup_scripts/build_msgs.sh), and the ament layout that
# lets `ros2 run ost_ros ...` / `ros2 launch ost_ros team.launch.py` find the nodes.
#
#   bringup_scripts/setup.sh          # creates/updates the venv (default: <repo>/.venv)
#   OST_VENV=/path/venv  OST_PYTHON=/path/python3.12  bringup_scripts/setup.sh
#
# Says what it does on stderr, one line per stage with the time it took (venv created, wheels
# installed, interfaces built: bringup_scripts/stage.sh); a second run with nothing changed prints
# nothing there and returns in about a second (stamp files record the hash of the lock file and the
# packaging files, and of the interface files). Prints the venv path on stdout's last line.
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="${OST_VENV:-$repo/.venv}"
lock="$repo/requirements.lock"
. "$repo/bringup_scripts/stage.sh"

die() { stage_break; echo "setup: error: $*" >&2; exit 2; }

is_py312() {  # prints nothing; true when "$1" runs and is CPython 3.12
  "$1" -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 12) else 1)' >/dev/null 2>&1
}

find_python() {
  local tried=() cand
  if [ -n "${OST_PYTHON:-}" ]; then
    is_py312 "$OST_PYTHON" && { echo "$OST_PYTHON"; return; }
    die "OST_PYTHON=$OST_PYTHON is not a working CPython 3.12"
  fi
  tried+=("OST_PYTHON (unset)")
  if command -v python3.12 >/dev/null 2>&1; then
    cand="$(command -v python3.12)"
    is_py312 "$cand" && { echo "$cand"; return; }
    tried+=("$cand (does not run; a pyenv shim needs PYENV_VERSION)")
  else
    tried+=("python3.12 on PATH (not found)")
  fi
  local root="${PYENV_ROOT:-$HOME/.pyenv}"
  for cand in "$root"/versions/3.12*/bin/python3; do
    [ -x "$cand" ] || continue
    is_py312 "$cand" && { echo "$cand"; return; }
    tried+=("$cand")
  done
  tried+=("$root/versions/3.12*/bin/python3")
  die "no CPython 3.12 found (ROS 2 Jazzy wheels need exactly 3.12); tried: $(IFS=';'; echo "${tried[*]}"). Set OST_PYTHON."
}

stamp_of() {
  cat "$lock" "$repo/setup.py" "$repo/setup.cfg" "$repo/package.xml" | sha256sum | cut -d' ' -f1
}

# The ROS side of an editable install (pip installs no data_files for it): the ament index
# marker, package.xml and launch files under VENV/share, the node executables under
# VENV/lib/ost_ros — what `ros2 pkg executables`, `ros2 run` and `ros2 launch` look for with
# AMENT_PREFIX_PATH=VENV. Symlinks into the repository, like the editable install itself.
ament_register() {
  mkdir -p "$venv/share/ament_index/resource_index/packages" "$venv/share/ost_ros" "$venv/lib/ost_ros"
  : > "$venv/share/ament_index/resource_index/packages/ost_ros"
  ln -sfn "$repo/package.xml" "$venv/share/ost_ros/package.xml"
  # a directory of links, not a link: ros2 launch walks share/ost_ros without following links
  [ -L "$venv/share/ost_ros/launch" ] && rm "$venv/share/ost_ros/launch"
  mkdir -p "$venv/share/ost_ros/launch"
  find "$venv/share/ost_ros/launch" -maxdepth 1 -type l -delete
  for f in "$repo"/launch/*.launch.py; do ln -sfn "$f" "$venv/share/ost_ros/launch/"; done
  for exe in world_node agent_node watch_node membership_node; do ln -sfn "$venv/bin/$exe" "$venv/lib/ost_ros/$exe"; done
}

# Bytecode of the packages (only what is stale): with PYTHONDONTWRITEBYTECODE set, as on our CI
# machines, every node would otherwise compile them at start (~80 ms of CPU per process).
compile() {
  (cd "$repo" && "$venv/bin/python" -m compileall -q agent_node world_node ost_msgs_py ost_ros >/dev/null)
}

finish() {  # every run: the interfaces (rebuilt only when a .msg changed) and the ament layout
  bash "$repo/bringup_scripts/build_msgs.sh" "$venv"
  ament_register
}

want="$(stamp_of)"
if [ -x "$venv/bin/python" ] && [ -f "$venv/.ost-stamp" ] && [ "$(cat "$venv/.ost-stamp")" = "$want" ] \
   && is_py312 "$venv/bin/python"; then
  compile
  finish
  echo "$venv"
  exit 0
fi

py="$(find_python)"
if [ ! -x "$venv/bin/python" ] || ! is_py312 "$venv/bin/python"; then
  stage_begin "creating $venv"
  rm -rf "$venv"
  "$py" -m venv "$venv"
  stage_end "venv created, $venv with $py"
fi
stage_begin "installing the pinned wheels (requirements.lock; the first time about a minute)"
log="$venv/setup.log"
pip_install() {  # pip's chatter goes to the log; shown only when pip fails
  if ! "$venv/bin/python" -m pip install -q --disable-pip-version-check "$@" >>"$log" 2>&1; then
    stage_break
    tail -n 30 "$log" >&2
    die "pip install $* failed (full log: $log)"
  fi
}
: > "$log"
pip_install --upgrade "pip==26.3"
pip_install -r "$lock"
pip_install --no-deps --no-build-isolation -e "$repo"
compile
stage_end "wheels installed"
finish
echo "$want" > "$venv/.ost-stamp"
echo "$venv"
