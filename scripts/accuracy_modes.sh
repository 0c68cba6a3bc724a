#!/usr/bin/env bash
# Consensus against naive over drawn drives, each replayed under K jitter seeds in both modes.
# A single replay of a drive moves by a factor of two or more under rounding-level changes on
# hard starts (docs/accuracy.md, "Random settings", "Consensus against naive"), so one replay per
# drive and mode is not enough to compare them. This takes the drives of `accuracy_random.sh
# --draw SEED:COUNT` (its --list), makes their captures where OUT_DIR lacks them (the folders of
# an `accuracy_random.sh` run into the same OUT_DIR are reused), replays each with --jitter-seed
# 1..K in each mode, and prints per drive the median ATE of the K replays in each mode and their
# ratio, then the geometric mean of the ratio consensus / naive over all drives, over those with
# 8-12 movers and over those started from rest, with how many drives consensus is lower on.
# Usage: scripts/accuracy_modes.sh [BUILD_DIR] [OUT_DIR] --draw SEED:COUNT [K]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build/release}
out=${2:-$root/out/accuracy-modes}
shift $(($# < 2 ? $# : 2))
if [[ ${1:-} != --draw || ! ${2:-} =~ ^[0-9]+:[0-9]+$ ]]; then
  echo "accuracy_modes.sh: usage: accuracy_modes.sh BUILD_DIR OUT_DIR --draw SEED:COUNT [K] (got '$*')" >&2
  exit 2
fi
draw=$2
k=${3:-3}
[[ $k =~ ^[1-9][0-9]*$ ]] || { echo "accuracy_modes.sh: K must be a positive number of seeds (got '$k')" >&2; exit 2; }
cndt=$build/src/apps/cndt
# The draw's drives (name and `cndt sim` arguments) and their captures, made where missing.
mkdir -p "$out"
list=$out/drives.txt
bash "$root/scripts/accuracy_random.sh" "$build" "$out" --draw "$draw" --list >"$list"
# shellcheck source=scripts/replay_eval.sh
source "$root/scripts/replay_eval.sh"
export cndt out
# shellcheck disable=SC2016 # expanded by the inner shell
xargs -P 2 -L 1 bash -c 'sim_once "$out/$0" "$@"' <"$list"
# shellcheck disable=SC2016 # expanded by the inner shell
cut -d' ' -f1 "$list" |
  while read -r name; do
    for mode in consensus naive; do
      for seed in $(seq 1 "$k"); do echo "$out/$name $mode $seed"; done
    done
  done | xargs -P 2 -L 1 bash -c 'replay_eval "$0" "$0/jitter-$1-$2" --mode "$1" --jitter-seed "$2"'
python3 - "$out" "$k" "$list" <<'PY'
import json, math, re, statistics, sys
out, k, listing = sys.argv[1], int(sys.argv[2]), sys.argv[3]
drives = [line.rstrip("\n").split(" ", 1) for line in open(listing) if line.strip()]
def median_ate(name, mode):
    return statistics.median(
        json.load(open(f"{out}/{name}/jitter-{mode}-{s}/eval.json"))["ate_rmse_m"]
        for s in range(1, k + 1))
print(f"| drive | settings | consensus ATE m (median of {k}) | naive | consensus / naive |")
print("|---|---|---|---|---|")
rows = []
for name, args in drives:
    c, n = median_ate(name, "consensus"), median_ate(name, "naive")
    movers = int(re.search(r"--movers (\d+)", args).group(1))
    rows.append((c, n, movers, "--start-still" in args))
    print(f"| {name} | `{args}` | {c:.4f} | {n:.4f} | {c / n:.2f} |")
print()
for label, subset in (("all", rows), ("8-12 movers", [r for r in rows if r[2] >= 8]),
                      ("started from rest", [r for r in rows if r[3]])):
    if not subset:
        continue
    g = math.exp(statistics.mean(math.log(c / n) for c, n, _, _ in subset))
    lower = sum(c < n for c, n, _, _ in subset)
    print(f"{label}: {len(subset)} drives, geometric mean of consensus / naive {g:.3f},"
          f" consensus lower on {lower}")
PY
