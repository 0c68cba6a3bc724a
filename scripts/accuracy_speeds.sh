#!/usr/bin/env bash
# Starts at speed (docs/odometry.md, "Starting at speed"): 20 s street drives at 20-40 m/s and at
# 12-20 m/s with the sensor at 300 rpm, loop and campus drives above their own speeds, seeds 5-7,
# replayed with the start search held at 2 m (odometry.max_speed_mps = 0) and growing (the
# default), scored by `cndt eval`. Prints per drive the worst frame-to-frame error of the first
# five pairs and the ATE, held -> growing.
# Usage: scripts/accuracy_speeds.sh [BUILD_DIR] [OUT_DIR]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build/release}
out=${2:-$root/out/speeds}
cndt=$build/src/apps/cndt
mkdir -p "$out"
printf '[odometry]\nmax_speed_mps = 0\n' >"$out/held.toml"
score() {  # eval.json -> "first-five-pairs-worst ate"
  python3 -c 'import json, sys
j = json.load(open(sys.argv[1]))
print("%.3f %.3f" % (max(f[1] for f in j["rpe_per_frame"][:5]), j["ate_rmse_m"]))' "$1"
}
echo "| drive | first pairs m, held -> growing | ATE m, held -> growing |"
echo "|---|---|---|"
drive() {  # scene speed seed [sim options]
  local scene=$1 speed=$2 seed=$3
  shift 3
  local dir=$out/$scene-$speed-$seed${1:+-rpm300}
  [[ -f $dir/capture.pcap ]] || "$cndt" sim --scene "$scene" --duration 20 --speed "$speed" \
    --seed "$seed" "$@" --out "$dir" >/dev/null 2>&1
  "$cndt" replay "$dir/capture.pcap" --out "$dir/held" --config "$out/held.toml" >/dev/null 2>&1
  "$cndt" replay "$dir/capture.pcap" --out "$dir/growing" >/dev/null 2>&1
  "$cndt" eval --gt "$dir/groundtruth.tum" --est "$dir/held/trajectory.tum" >"$dir/held/eval.json"
  "$cndt" eval --gt "$dir/groundtruth.tum" --est "$dir/growing/trajectory.tum" \
    >"$dir/growing/eval.json"
  read -r p0 a0 <<<"$(score "$dir/held/eval.json")"
  read -r p1 a1 <<<"$(score "$dir/growing/eval.json")"
  echo "| $(basename "$dir") | $p0 -> $p1 | $a0 -> $a1 |"
}
for seed in 5 6 7; do
  for speed in 20 25 30 35 40; do drive street "$speed" "$seed"; done
  for speed in 12 16 20; do drive street "$speed" "$seed" --rpm 300; done
  for speed in 14 20; do drive loop "$speed" "$seed"; done
  for speed in 8 12; do drive campus "$speed" "$seed"; done
done
