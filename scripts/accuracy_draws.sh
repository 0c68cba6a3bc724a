#!/usr/bin/env bash
# One build's odometry over the 28 drives of accuracy_seeds.sh (30 s simulated street, campus and
# loop captures), each replayed under several jitter seeds (`cndt replay --jitter-seed`; 0 = no
# jitter), scored by `cndt eval`: ATE, RTE and RPE over all draws and per scene, and the worst
# draws. A single replay is one draw of a result that rounding moves by centimetres
# (docs/accuracy.md, "Sensitivity"), so compare two builds by running this on each.
# Usage: scripts/accuracy_draws.sh BUILD_DIR OUT_DIR [MODE] [JITTER_SEEDS...]
#   MODE consensus (default) or naive; JITTER_SEEDS default "0 1" (56 replays, about 7 minutes
#   on two cores). The captures are those of accuracy_seeds.sh, made here when missing.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=$1
results=$2
mode=${3:-consensus}
shift $(($# < 3 ? $# : 3))
seeds=("$@")
[[ ${#seeds[@]} -gt 0 ]] || seeds=(0 1)
cndt=$build/src/apps/cndt
captures=$root/out/accuracy-seeds
mkdir -p "$captures" "$results"
# shellcheck source=scripts/accuracy_drives.sh
source "$root/scripts/accuracy_drives.sh"
# shellcheck source=scripts/replay_eval.sh
source "$root/scripts/replay_eval.sh"
jobs=()
for d in "${drives[@]}"; do
  for j in "${seeds[@]}"; do jobs+=("$d $j"); done
done
run() {  # scene-seed-movers jitter-seed
  local dir=$captures/$1 out=$results/$1-j$2
  drive_capture "$1" 30 "$captures"
  replay_eval "$dir" "$out" --mode "$mode" --jitter-seed "$2"
}
export -f run drive_capture
export cndt captures results mode
# shellcheck disable=SC2016 # expanded by the inner shell
printf '%s\n' "${jobs[@]}" | xargs -P 2 -L 1 bash -c 'run "$0" "$1"'
python3 - "$results" "${jobs[@]}" <<'PY'
import json, statistics, sys
results, jobs = sys.argv[1], [j.split() for j in sys.argv[2:]]
rows = []
for drive, jitter in jobs:
    e = json.load(open(f"{results}/{drive}-j{jitter}/eval.json"))
    rows.append((f"{drive}-j{jitter}", e["ate_rmse_m"], e["rte_percent"],
                 e["rpe_translation_rmse_m"]))
def line(name, sel):
    a, p = ([r[k] for r in sel] for k in (1, 3))
    t = [r[2] for r in sel if r[2] is not None]  # RTE is null on a path under 20 m
    rte = f"{statistics.mean(t):.3f} / {statistics.median(t):.3f}" if t else "n/a"
    return (f"| {name} | {len(sel)} | {statistics.mean(a):.4f} / {statistics.median(a):.4f} / "
            f"{max(a):.3f} | {sum(x > 0.1 for x in a)} | {rte} | {statistics.mean(p):.4f} |")
print("| draws | n | ATE m mean / median / worst | ATE > 0.1 m | RTE % mean / median | RPE m mean |")
print("|---|---|---|---|---|---|")
print(line("all", rows))
for scene in ("street", "campus", "loop"):
    print(line(scene, [r for r in rows if r[0].startswith(scene + "-")]))
print()
worst = sorted(rows, key=lambda r: -r[1])[:4]
print("Worst draws (ATE m; scene-seed-movers, then the jitter seed): "
      + ", ".join(f"{r[0]} {r[1]:.3f}" for r in worst))
PY
