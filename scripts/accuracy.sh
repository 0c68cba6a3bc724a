#!/usr/bin/env bash
# Regenerates the odometry accuracy table of docs/accuracy.md: simulated 60 s captures of every
# scene with 4 movers (and street with 8), replayed in consensus and naive mode, scored by
# `cndt eval`. Usage: scripts/accuracy.sh [BUILD_DIR] [SECONDS]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build/release}
seconds=${2:-60}
cndt=$build/src/apps/cndt
out=$root/out/accuracy
mkdir -p "$out"
# shellcheck source=scripts/replay_eval.sh
source "$root/scripts/replay_eval.sh"
row() {  # scene movers mode
  local dir=$out/$1-m$2
  sim_once "$dir" --scene "$1" --duration "$seconds" --movers "$2" --seed 1
  replay_eval "$dir" "$dir/$3" --mode "$3"
  python3 - "$1" "$2" "$3" "$dir/$3/eval.json" "$dir/$3/summary.json" <<'PY'
import json, sys
e = json.load(open(sys.argv[4])); s = json.load(open(sys.argv[5]))
def num(x, spec):  # segment errors are null on a path under 20 m
    return "n/a" if x is None else format(x, spec)
print(f"| {sys.argv[1]} | {sys.argv[2]} | {sys.argv[3]} | {e['path_length_m']:.0f} | {e['ate_rmse_m']:.3f} | "
      f"{num(e['rte_percent'], '.2f')} | {num(e['rre_deg_per_m'], '.4f')} | {e['rpe_translation_rmse_m']:.4f} | "
      f"{e['start_aligned']['height_error_end_m']:.2f} | {e['start_aligned']['tilt_end_deg']:.2f} | "
      f"{s['iterations_mean']:.1f} | {s['odometry_ms_p50']:.0f} |")
PY
}
echo "| scene | movers | mode | path m | ATE RMSE m | RTE % | RRE deg/m | RPE m/frame | height error at end m | tilt at end deg | iterations | ms/scan p50 |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
for scene in street campus corridor loop; do
  for mode in consensus naive; do row "$scene" 4 "$mode"; done
done
for mode in consensus naive; do row street 8 "$mode"; done
