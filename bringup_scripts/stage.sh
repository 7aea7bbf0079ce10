# Sourced by setup.sh, build_msgs.sh and tests/ros2_tools.sh: one line on stderr per stage of the
# set-up that had something to do, with the time it took ("setup: wheels installed (1 m 2 s)"); a
# run with nothing to do prints nothing. On a terminal the line says what is under way until the
# stage ends. OST_SETUP_QUIET=1 silences the lines (errors still show).
_stage_t0=0 _stage_open=0

_stage_say() { [ "${OST_SETUP_QUIET:-0}" != 1 ]; }

stage_begin() {  # stage_begin "installing the pinned wheels"
  _stage_t0=$(date +%s%N)
  if _stage_say && [ -t 2 ]; then printf 'setup: %s ...' "$1" >&2; _stage_open=1; fi
}

stage_end() {  # stage_end "wheels installed"
  local ms=$(( ($(date +%s%N) - _stage_t0) / 1000000 )) took
  if [ "$ms" -lt 10000 ]; then took="$(( ms / 1000 )).$(( ms % 1000 / 100 )) s"
  elif [ "$ms" -lt 60000 ]; then took="$(( ms / 1000 )) s"
  else took="$(( ms / 60000 )) m $(( ms % 60000 / 1000 )) s"; fi
  if [ "$_stage_open" = 1 ]; then printf '\r\033[K' >&2; _stage_open=0; fi
  if _stage_say; then echo "setup: $1 ($took)" >&2; fi
}

stage_break() {  # before an error message: end an open "... under way" line
  if [ "$_stage_open" = 1 ]; then echo >&2; _stage_open=0; fi
}
