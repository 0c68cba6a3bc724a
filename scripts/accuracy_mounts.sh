#!/usr/bin/env bash
# Odometry with the sensor mounted other than level and facing forward (docs/accuracy.md,
# "Mounting"): 20 s drives of street, campus and loop (seed 1) for each `cndt sim --mount`
# below, replayed in the default mode and scored by `cndt eval`, the height and tilt at the
# end with the estimate placed on the truth by its first pose.
# Usage: scripts/accuracy_mounts.sh [BUILD_DIR] [OUT_DIR]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build/release}
out=${2:-$root/out/mounts}
cndt=$build/src/apps/cndt
mkdir -p "$out"
mounts=("0 0 0" "0 10 0" "0 -10 0" "0 30 0" "0 0 90" "0 0 180" "90 0 0")
echo "| mount (roll pitch yaw, deg) | scene | ATE RMSE m | RTE % | RPE m/frame | height at end m | tilt at end deg | flagged degenerate |"
echo "|---|---|---|---|---|---|---|---|"
for mount in "${mounts[@]}"; do
  for scene in street campus loop; do
    read -r -a m <<<"$mount"
    dir=$out/$scene-${m[0]}-${m[1]}-${m[2]}
    [[ -f $dir/capture.pcap ]] || "$cndt" sim --scene "$scene" --duration 20 --seed 1 \
      --mount "${m[@]}" --out "$dir" >/dev/null 2>&1
    "$cndt" replay "$dir/capture.pcap" --out "$dir/replay" >/dev/null 2>&1
    "$cndt" eval --gt "$dir/groundtruth.tum" --est "$dir/replay/trajectory.tum" |
      python3 -c 'import csv, json, sys
j = json.load(sys.stdin)
rows = [r for r in csv.DictReader(open(sys.argv[3])) if int(r["flags"]) & 32 == 0]  # skipped: no pose
flagged = sum(1 for r in rows if int(r["flags"]) & 8)
s = j["start_aligned"]
rte = "n/a" if j["rte_percent"] is None else "%.3f" % j["rte_percent"]  # null under 20 m
print("| %s | %s | %.4f | %s | %.4f | %.2f | %.2f | %d of %d |" % (sys.argv[1], sys.argv[2],
      j["ate_rmse_m"], rte, j["rpe_translation_rmse_m"], s["height_error_end_m"],
      s["tilt_end_deg"], flagged, len(rows)))' "$mount" "$scene" "$dir/replay/scans.csv"
  done
done
