#!/usr/bin/env bash
# Odometry on 20 s drives with settings drawn at random: scene, seed, movers, rotor speed, vehicle
# speed, sensor height, range noise, packet loss, mount, a start from rest, dual return, body
# motion. By default the 28 drives drawn once and written down here (seeds 100-127; the table of
# docs/accuracy.md, "Random settings"); with --draw SEED:COUNT, COUNT new drives drawn from SEED
# (stops and outages among the settings too; seeds 1000 x SEED on), so that each draw is a set
# of worlds and settings never tuned on. (Clock steps are left out: the trajectory keeps the
# sensor's stamps, which `cndt eval` cannot pair across a step back; docs/odometry.md, "Clock
# jumps".) Replayed in the default mode (other arguments go to `cndt replay`, e.g. --mode naive
# or --config FILE) and scored by `cndt eval`: one row per drive (ATE, RTE, RRE, RPE, the height
# error at the end), the worst of each and the median ATE. With --list, only prints the drives
# (name and `cndt sim` arguments, one a line) and runs nothing.
# Usage: scripts/accuracy_random.sh [BUILD_DIR] [OUT_DIR] [--draw SEED:COUNT] [--list] [REPLAY_ARGS...]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build/release}
out=${2:-$root/out/accuracy-random}
shift $(($# < 2 ? $# : 2))
draw=""
if [[ ${1:-} == --draw ]]; then
  [[ ${2:-} =~ ^[0-9]+:[0-9]+$ ]] || { echo "accuracy_random.sh: --draw takes SEED:COUNT, e.g. 7:32 (got '${2:-}')" >&2; exit 2; }
  draw=$2
  shift 2
fi
list=false
if [[ ${1:-} == --list ]]; then
  list=true
  shift
fi
replay_args=("$@")
cndt=$build/src/apps/cndt
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
if [[ -n $draw ]]; then
  mapfile -t drives < <(python3 - "$draw" <<'PY'
import random, sys
seed, count = (int(v) for v in sys.argv[1].split(":"))
r = random.Random(seed)
for i in range(count):
    a = [f"--scene {r.choice(['street', 'campus', 'loop'])}", f"--seed {1000 * seed + i}",
         "--duration 20", f"--movers {r.choice([0, 2, 4, 6, 8, 12])}"]
    if r.random() < 0.3: a.append(f"--rpm {r.choice([300, 420, 480, 720, 900, 1200])}")
    if r.random() < 0.3: a.append(f"--speed {r.uniform(1.0, 16.0):.1f}")
    if r.random() < 0.2: a.append(f"--height {r.uniform(0.6, 2.5):.2f}")
    if r.random() < 0.3: a.append(f"--noise {r.uniform(0.003, 0.03):.3f}")
    if r.random() < 0.2: a.append(f"--drop-rate {r.uniform(0.02, 0.3):.2f}")
    if r.random() < 0.2:
        a.append(f"--mount {r.uniform(-5, 5):.1f} {r.uniform(-5, 5):.1f} {r.uniform(-180, 180):.1f}")
    if r.random() < 0.25: a.append(f"--start-still {r.uniform(0.5, 3):.1f}")
    if r.random() < 0.15: a.append(f"--stop {r.uniform(5, 12):.1f} {r.uniform(1, 4):.1f}")
    if r.random() < 0.1: a.append(f"--outage {r.uniform(5, 12):.1f} {r.uniform(0.2, 1.0):.1f}")
    if r.random() < 0.15: a.append("--dual")
    if r.random() < 0.2: a.append(f"--body-motion {r.uniform(0, 2.5):.2f}")
    print(f"d{seed}-{i:02d} " + " ".join(a))
PY
  )
fi
if $list; then
  printf '%s\n' "${drives[@]}"
  exit 0
fi
mkdir -p "$out"
# shellcheck source=scripts/replay_eval.sh
source "$root/scripts/replay_eval.sh"
run() {  # NAME SIM_ARGS...
  local dir=$out/$1
  shift
  sim_once "$dir" "$@"
  replay_eval "$dir" "$dir/replay" "${replay_args[@]}"
}
export -f run
export cndt out
export REPLAY_ARGS="${replay_args[*]}"
# shellcheck disable=SC2016 # expanded by the inner shell
printf '%s\n' "${drives[@]}" |
  xargs -P 2 -L 1 bash -c 'read -r -a replay_args <<<"$REPLAY_ARGS"; run "$0" "$@"'
python3 - "$out" "${drives[@]}" <<'PY'
import json, statistics, sys
out, drives = sys.argv[1], sys.argv[2:]
print("| drive | settings | ATE RMSE m | RTE % | RRE deg/m | RPE m/frame | height at end m |")
print("|---|---|---|---|---|---|---|")
worst, ates = [0.0] * 5, []
for d in drives:
    name, args = d.split(" ", 1)
    j = json.load(open(f"{out}/{name}/replay/eval.json"))
    row = [j["ate_rmse_m"], j["rte_percent"], j["rre_deg_per_m"], j["rpe_translation_rmse_m"],
           j["start_aligned"]["height_error_end_m"]]
    # RTE and RRE are null on a path shorter than 20 m (no segment): shown as n/a.
    worst = [w if b is None else max(w, abs(b)) for w, b in zip(worst, row)]
    ates.append(row[0])
    cells = ["n/a" if v is None else f"{v:.{n}f}" for v, n in zip(row, (4, 3, 4, 4, 2))]
    print(f"| {name} | `{args}` | " + " | ".join(cells) + " |")
print()
print("worst: ATE %.4f m, RTE %.3f %%, RRE %.4f deg/m, RPE %.4f m, |height at end| %.2f m" % tuple(worst),
      "over %d drives; ATE median %.4f m" % (len(drives), statistics.median(ates)))
PY
