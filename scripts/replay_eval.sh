# Sourced by the accuracy scripts (it needs `cndt`, the path of the cndt binary, set): a drive's
# capture made once, and a replay of it scored against its ground truth. Exported, so that
# `xargs ... bash -c` workers can call them.
# shellcheck shell=bash disable=SC2154 # cndt is set by the scripts that source this

# sim_once DIR SIM_ARGS...: `cndt sim SIM_ARGS --out DIR`, unless DIR already holds a capture.
sim_once() {
  local dir=$1
  shift
  [[ -f $dir/capture.pcap ]] || "$cndt" sim "$@" --out "$dir" >/dev/null 2>&1
}

# replay_eval DIR RUN [REPLAY_ARGS...]: replays DIR/capture.pcap into RUN with REPLAY_ARGS and
# writes `cndt eval` of RUN/trajectory.tum against DIR/groundtruth.tum to RUN/eval.json.
replay_eval() {
  local dir=$1 run=$2
  shift 2
  "$cndt" replay "$dir/capture.pcap" --out "$run" "$@" >/dev/null 2>&1
  "$cndt" eval --gt "$dir/groundtruth.tum" --est "$run/trajectory.tum" >"$run/eval.json"
}

export -f sim_once replay_eval
