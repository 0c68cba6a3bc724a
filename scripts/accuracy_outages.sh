#!/usr/bin/env bash
# Odometry across a data outage (docs/odometry.md, "Gaps in the data"): simulated 20 s drives
# with nothing received for 0.3, 1, 3 or 6 s from 8 s on (`cndt sim --outage`), replayed in the
# default mode and scored by `cndt eval` against the whole ground truth.
# Usage: scripts/accuracy_outages.sh [BUILD_DIR] [OUT_DIR]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build/release}
out=${2:-$root/out/outages}
cndt=$build/src/apps/cndt
mkdir -p "$out"
echo "| drive | no outage | 0.3 s | 1 s | 3 s | 6 s |"
echo "|---|---|---|---|---|---|"
for drive in street-5 street-7 campus-2 loop-4; do
  scene=${drive%-*}
  seed=${drive#*-}
  line="| $drive |"
  for gap in 0 0.3 1 3 6; do
    dir=$out/$drive-gap$gap
    outage=()
    [[ $gap == 0 ]] || outage=(--outage 8 "$gap")
    [[ -f $dir/capture.pcap ]] ||
      "$cndt" sim --scene "$scene" --duration 20 --seed "$seed" "${outage[@]}" --out "$dir" >/dev/null 2>&1
    "$cndt" replay "$dir/capture.pcap" --out "$dir/replay" >/dev/null 2>&1
    ate=$("$cndt" eval --gt "$dir/groundtruth.tum" --est "$dir/replay/trajectory.tum" |
      python3 -c 'import json, sys; print("%.4f" % json.load(sys.stdin)["ate_rmse_m"])')
    line="$line $ate |"
  done
  echo "$line"
done
