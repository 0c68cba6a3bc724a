#!/usr/bin/env bash
# How far the odometry's accuracy depends on chance at the level of rounding: each 60 s capture
# of docs/accuracy.md (street, campus and loop with 4 movers, street with 8; seed 1) replayed in
# both modes without jitter and with --jitter-seed 1..K (every match's initial guess moved by at
# most 0.5e-9 m / rad), scored by `cndt eval`. Prints one row per capture and mode: the ATE of
# each run, then their median and worst. Usage: scripts/accuracy_spread.sh [BUILD_DIR] [SECONDS] [K]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build/release}
seconds=${2:-60}
k=${3:-3}
cndt=$build/src/apps/cndt
out=$root/out/accuracy
mkdir -p "$out"
ate() {  # dir run-name jitter-seed mode
  "$cndt" replay "$1/capture.pcap" --out "$1/$2" --mode "$4" --jitter-seed "$3" >/dev/null 2>&1
  "$cndt" eval --gt "$1/groundtruth.tum" --est "$1/$2/trajectory.tum" |
    python3 -c 'import json, sys; print("%.3f" % json.load(sys.stdin)["ate_rmse_m"])'
}
echo "| scene | movers | mode | ATE m: no jitter, seeds 1-$k | median | worst |"
echo "|---|---|---|---|---|---|"
for cell in street:4 campus:4 loop:4 street:8; do
  scene=${cell%:*} movers=${cell#*:}
  dir=$out/$scene-m$movers
  [[ -f $dir/capture.pcap ]] ||
    "$cndt" sim --scene "$scene" --duration "$seconds" --movers "$movers" --seed 1 --out "$dir" >/dev/null
  for mode in consensus naive; do
    ates=()
    for seed in $(seq 0 "$k"); do
      ates+=("$(ate "$dir" "$mode-jitter$seed" "$seed" "$mode")")
    done
    python3 - "$scene" "$movers" "$mode" "${ates[@]}" <<'PY'
import statistics, sys
scene, movers, mode, *ates = sys.argv[1:]
v = [float(a) for a in ates]
print(f"| {scene} | {movers} | {mode} | {' / '.join(ates)} | {statistics.median(v):.3f} | {max(v):.3f} |")
PY
  done
done
