#!/usr/bin/env bash
# Odometry across a data outage and across a sensor clock step (docs/odometry.md, "Gaps in the
# data"): simulated 20 s drives with nothing received for 0.3, 1, 3 or 6 s from 8 s on
# (`cndt sim --outage`), and with the sensor clock stepped by -5, +0.5 or +5 s at 8 s
# (`cndt sim --clock-step`), replayed in the default mode and scored by `cndt eval` against the
# whole ground truth (after a clock step, with the step taken out of the estimate's stamps).
# Usage: scripts/accuracy_outages.sh [BUILD_DIR] [OUT_DIR]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build/release}
out=${2:-$root/out/outages}
cndt=$build/src/apps/cndt
mkdir -p "$out"
drives=(street-5 street-7 campus-2 loop-4)

# ATE RMSE of the replay in $1 (a capture folder) against its ground truth; $2: the clock step
# to take out of the stamps after it, s.
ate() {
  "$cndt" replay "$1/capture.pcap" --out "$1/replay" >/dev/null 2>&1
  python3 - "$1/replay/trajectory.tum" "$1/replay/true_clock.tum" "$2" <<'PY'
import sys
src, dst, step = sys.argv[1], sys.argv[2], float(sys.argv[3])
rows = [l.split() for l in open(src) if l.strip() and not l.startswith('#')]
shifted, prev, out = False, None, []
for f in rows:
    t = float(f[0])
    # The first stamp whose step from the last one is nearer the clock step than a revolution.
    if step != 0 and prev is not None and not shifted and abs(t - prev - step) < abs(t - prev):
        shifted = True
    prev = t
    f[0] = "%.9f" % (t - step if shifted else t)
    out.append(" ".join(f))
open(dst, "w").write("\n".join(out) + "\n")
PY
  "$cndt" eval --gt "$1/groundtruth.tum" --est "$1/replay/true_clock.tum" |
    python3 -c 'import json, sys; print("%.4f" % json.load(sys.stdin)["ate_rmse_m"])'
}

echo "Outage from 8 s (ATE RMSE, m):"
echo
echo "| drive | no outage | 0.3 s | 1 s | 3 s | 6 s |"
echo "|---|---|---|---|---|---|"
for drive in "${drives[@]}"; do
  line="| $drive |"
  for gap in 0 0.3 1 3 6; do
    dir=$out/$drive-gap$gap
    fault=()
    [[ $gap == 0 ]] || fault=(--outage 8 "$gap")
    [[ -f $dir/capture.pcap ]] || "$cndt" sim --scene "${drive%-*}" --duration 20 \
      --seed "${drive#*-}" "${fault[@]}" --out "$dir" >/dev/null 2>&1
    line="$line $(ate "$dir" 0) |"
  done
  echo "$line"
done
echo
echo "Sensor clock stepped at 8 s (ATE RMSE, m):"
echo
echo "| drive | -5 s | +0.5 s | +5 s |"
echo "|---|---|---|---|"
for drive in "${drives[@]}"; do
  line="| $drive |"
  for step in -5 0.5 5; do
    dir=$out/$drive-step$step
    [[ -f $dir/capture.pcap ]] || "$cndt" sim --scene "${drive%-*}" --duration 20 \
      --seed "${drive#*-}" --clock-step 8 "$step" --out "$dir" >/dev/null 2>&1
    line="$line $(ate "$dir" "$step") |"
  done
  echo "$line"
done
