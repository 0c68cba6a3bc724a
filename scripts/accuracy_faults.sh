#!/usr/bin/env bash
# Odometry under faults and sensor settings other than the defaults (docs/accuracy.md, "Other
# seeds and faults"): 20 s drives of street, campus and loop for world seeds 11-20, each with
# one of six settings in turn (12 movers; 20 % packet loss; dual return at 900 rpm; 300 rpm with
# 3 cm range noise; no movers; 1200 rpm with 5 % loss), replayed in the default mode and scored
# by `cndt eval`. Prints one row per drive and the worst ATE, RTE and RPE.
# Usage: scripts/accuracy_faults.sh [BUILD_DIR] [OUT_DIR]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build/release}
out=${2:-$root/out/faults}
cndt=$build/src/apps/cndt
mkdir -p "$out"
settings=("--movers 12" "--drop-rate 0.2" "--dual --rpm 900" "--rpm 300 --noise 0.03"
  "--movers 0" "--rpm 1200 --drop-rate 0.05")
echo "| drive | setting | ATE RMSE m | RTE % | RPE m/frame |"
echo "|---|---|---|---|---|"
i=0
rows=()
for seed in 11 12 13 14 15 16 17 18 19 20; do
  for scene in street campus loop; do
    i=$((i + 1))
    read -r -a setting <<<"${settings[$((i % 6))]}"
    dir=$out/$scene-$seed
    [[ -f $dir/capture.pcap ]] || "$cndt" sim --scene "$scene" --duration 20 --seed "$seed" \
      "${setting[@]}" --out "$dir" >/dev/null 2>&1
    "$cndt" replay "$dir/capture.pcap" --out "$dir/replay" >/dev/null 2>&1
    row=$("$cndt" eval --gt "$dir/groundtruth.tum" --est "$dir/replay/trajectory.tum" |
      python3 -c 'import json, sys
j = json.load(sys.stdin)
rte = "n/a" if j["rte_percent"] is None else "%.3f" % j["rte_percent"]  # null under 20 m
print("%.4f %s %.4f" % (j["ate_rmse_m"], rte, j["rpe_translation_rmse_m"]))')
    read -r ate rte rpe <<<"$row"
    rows+=("$row")
    echo "| $scene-$seed | ${setting[*]} | $ate | $rte | $rpe |"
  done
done
printf '%s\n' "${rows[@]}" | python3 -c 'import sys
r = [l.split() for l in sys.stdin if l.strip()]
rte = [float(x[1]) for x in r if x[1] != "n/a"]
print()
print("worst: ATE %.4f m, RTE %s %%, RPE %.4f m over %d drives" %
      (max(float(x[0]) for x in r), "%.3f" % max(rte) if rte else "n/a",
       max(float(x[2]) for x in r), len(r)))'
