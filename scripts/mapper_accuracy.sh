#!/usr/bin/env bash
# Regenerates the mapper table of docs/mapper.md: simulated loop and street captures (4 movers,
# seed 1) replayed with the mapper; the odometry (odometry.tum), the map-corrected poses as
# published (trajectory.tum) and the refined keyframe poses (refined.tum) scored by `cndt eval`.
# Then localization: a second loop capture of the same world (seed 2, other movers, noise and
# timing) replayed against the first one's map, frozen.
# Usage: scripts/mapper_accuracy.sh [BUILD_DIR] [SECONDS]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build/release}
seconds=${2:-120}
cndt=$build/src/apps/cndt
out=$root/out/mapper
mkdir -p "$out"
score() {  # label dir run
  for f in odometry trajectory refined; do
    "$cndt" eval --gt "$2/groundtruth.tum" --est "$2/$3/$f.tum" > "$2/$3/$f.eval.json"
  done
  python3 - "$1" "$2/$3" <<'PY'
import json, sys
d = sys.argv[2]
e = {f: json.load(open(f"{d}/{f}.eval.json")) for f in ("odometry", "trajectory", "refined")}
s = json.load(open(f"{d}/summary.json"))
row = " | ".join(f"{e[f]['ate_rmse_m']:.3f} / {e[f]['rpe_translation_rmse_m']:.4f}"
                 for f in ("odometry", "trajectory", "refined"))
print(f"| {sys.argv[1]} | {row} | {s['keyframes']} | {s['mapper_ms_p50']:.0f} / "
      f"{s['mapper_ms_p99']:.0f} | {s['map_cm_median']:.3f} | {s['map_voxels']} |")
PY
}
sim() {  # name scene seed world_seed start
  [[ -f $out/$1/capture.pcap ]] || "$cndt" sim --scene "$2" --duration "$seconds" --movers 4 \
    --seed "$3" --world-seed "$4" --start-time "$5" --out "$out/$1" >/dev/null 2>&1
}
echo "| run | odometry ATE m / RPE m | published | refined | keyframes | mapper ms p50 / p99 per keyframe | median Cm vs map | map voxels |"
echo "|---|---|---|---|---|---|---|---|"
for scene in loop street; do
  sim "$scene" "$scene" 1 1 1767225600
  "$cndt" replay "$out/$scene/capture.pcap" --out "$out/$scene/map" \
    --save-map "$out/$scene/map.cndtmap" >/dev/null 2>&1
  score "$scene ${seconds} s, mapping" "$out/$scene" map
done
sim loop-b loop 2 1 1767300000.05
"$cndt" replay "$out/loop-b/capture.pcap" --out "$out/loop-b/loc" --map "$out/loop/map.cndtmap" \
  >/dev/null 2>&1
score "loop ${seconds} s, seed 2 localized in seed 1's map" "$out/loop-b" loc
