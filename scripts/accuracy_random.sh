#!/usr/bin/env bash
# Odometry on 28 drives of 20 s whose settings were drawn at random once and written down here
# (docs/odometry.md, "Pyramid while near"): scene, seed 100-127, movers, rotor speed, vehicle
# speed, sensor height, range noise, packet loss, mount, a start from rest, dual return, body
# motion. Replayed in the default mode (extra arguments go to `cndt replay`, e.g. --mode naive or
# --config FILE) and scored by `cndt eval`: one row per drive and the worst ATE, RTE and RPE.
# Usage: scripts/accuracy_random.sh [BUILD_DIR] [OUT_DIR] [REPLAY_ARGS...]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build/release}
out=${2:-$root/out/accuracy-random}
shift $(($# < 2 ? $# : 2))
replay_args=("$@")
cndt=$build/src/apps/cndt
mkdir -p "$out"
drives=(
  "r00 --scene campus --seed 100 --duration 20 --movers 8 --height 2.09 --noise 0.007 --drop-rate 0.24"
  "r01 --scene loop --seed 101 --duration 20 --movers 12 --noise 0.006 --drop-rate 0.12 --mount 2.9 5.9 70.0 --start-still 1.8"
  "r02 --scene street --seed 102 --duration 20 --movers 6"
  "r03 --scene loop --seed 103 --duration 20 --movers 0 --rpm 300 --noise 0.026 --dual"
  "r04 --scene campus --seed 104 --duration 20 --movers 0 --rpm 420 --speed 12.2 --start-still 2.8"
  "r05 --scene campus --seed 105 --duration 20 --movers 2 --mount -1.3 2.3 75.0"
  "r06 --scene street --seed 106 --duration 20 --movers 0 --speed 7.6 --noise 0.022"
  "r07 --scene loop --seed 107 --duration 20 --movers 6 --speed 13.0"
  "r08 --scene campus --seed 108 --duration 20 --movers 2 --rpm 1200 --mount -1.8 0.1 129.0 --start-still 1.1"
  "r09 --scene loop --seed 109 --duration 20 --movers 0 --noise 0.02 --dual"
  "r10 --scene street --seed 110 --duration 20 --movers 12 --mount 3.4 1.7 -73.0"
  "r11 --scene campus --seed 111 --duration 20 --movers 0 --rpm 420"
  "r12 --scene loop --seed 112 --duration 20 --movers 12"
  "r13 --scene campus --seed 113 --duration 20 --movers 0"
  "r14 --scene street --seed 114 --duration 20 --movers 6 --start-still 2.2"
  "r15 --scene loop --seed 115 --duration 20 --movers 4 --noise 0.008 --mount 3.7 2.9 -51.0"
  "r16 --scene campus --seed 116 --duration 20 --movers 2 --rpm 900 --noise 0.006"
  "r17 --scene loop --seed 117 --duration 20 --movers 0"
  "r18 --scene loop --seed 118 --duration 20 --movers 0"
  "r19 --scene loop --seed 119 --duration 20 --movers 8 --rpm 420 --speed 8.9"
  "r20 --scene street --seed 120 --duration 20 --movers 4 --speed 3.6"
  "r21 --scene street --seed 121 --duration 20 --movers 6 --rpm 420"
  "r22 --scene street --seed 122 --duration 20 --movers 2 --speed 11.3 --height 0.63 --noise 0.009"
  "r23 --scene campus --seed 123 --duration 20 --movers 2 --rpm 1200"
  "r24 --scene campus --seed 124 --duration 20 --movers 8"
  "r25 --scene loop --seed 125 --duration 20 --movers 0 --rpm 900 --speed 8.0 --noise 0.015"
  "r26 --scene loop --seed 126 --duration 20 --movers 0"
  "r27 --scene loop --seed 127 --duration 20 --movers 12"
)
run() {  # NAME SIM_ARGS...
  local dir=$out/$1
  shift
  [[ -f $dir/capture.pcap ]] || "$cndt" sim "$@" --out "$dir" >/dev/null 2>&1
  "$cndt" replay "$dir/capture.pcap" --out "$dir/replay" "${replay_args[@]}" >/dev/null 2>&1
  "$cndt" eval --gt "$dir/groundtruth.tum" --est "$dir/replay/trajectory.tum" >"$dir/replay/eval.json"
}
export -f run
export cndt out
export REPLAY_ARGS="${replay_args[*]}"
# shellcheck disable=SC2016 # expanded by the inner shell
printf '%s\n' "${drives[@]}" |
  xargs -P 2 -L 1 bash -c 'read -r -a replay_args <<<"$REPLAY_ARGS"; run "$0" "$@"'
python3 - "$out" "${drives[@]}" <<'PY'
import json, sys
out, drives = sys.argv[1], sys.argv[2:]
print("| drive | settings | ATE RMSE m | RTE % | RPE m/frame |")
print("|---|---|---|---|---|")
worst = [0.0, 0.0, 0.0]
for d in drives:
    name, args = d.split(" ", 1)
    j = json.load(open(f"{out}/{name}/replay/eval.json"))
    row = [j["ate_rmse_m"], j["rte_percent"], j["rpe_translation_rmse_m"]]
    worst = [max(a, b) for a, b in zip(worst, row)]
    print(f"| {name} | `{args}` | {row[0]:.4f} | {row[1]:.3f} | {row[2]:.4f} |")
print()
print("worst: ATE %.4f m, RTE %.3f %%, RPE %.4f m over %d drives" % (*worst, len(drives)))
PY
