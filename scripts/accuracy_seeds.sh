#!/usr/bin/env bash
# Consensus against naive over many seeds: 30 s simulated captures of street, campus and loop
# (seeds 1, 2, 5, 6, 8, 9, 10, 11 with 4 movers; seed 7 with 8 movers, street also seed 3 and
# 12 with 8), each replayed in both modes and scored by `cndt eval`. Prints one line per drive
# and the means per scene and per number of movers (docs/accuracy.md). Two replays at a time.
# Usage: scripts/accuracy_seeds.sh [BUILD_DIR] [SECONDS]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build/release}
seconds=${2:-30}
cndt=$build/src/apps/cndt
out=$root/out/accuracy-seeds
mkdir -p "$out"
# shellcheck source=scripts/accuracy_drives.sh
source "$root/scripts/accuracy_drives.sh"
run() {  # scene-seed-movers
  local dir=$out/$1
  drive_capture "$1" "$seconds" "$out"
  for mode in consensus naive; do
    "$cndt" replay "$dir/capture.pcap" --out "$dir/$mode" --mode "$mode" >/dev/null 2>&1
    "$cndt" eval --gt "$dir/groundtruth.tum" --est "$dir/$mode/trajectory.tum" \
      > "$dir/$mode/eval.json"
  done
}
export -f run drive_capture
export cndt out seconds
printf '%s\n' "${drives[@]}" | xargs -P 2 -I{} bash -c 'run {}'
python3 - "$out" "${drives[@]}" <<'PY'
import json, statistics, sys
out, drives = sys.argv[1], sys.argv[2:]
keys = [("ate_rmse_m", "ATE m"), ("rte_percent", "RTE %"), ("rre_deg_per_m", "RRE deg/m"),
        ("rpe_translation_rmse_m", "RPE m")]
ev = {d: {m: json.load(open(f"{out}/{d}/{m}/eval.json")) for m in ("consensus", "naive")}
      for d in drives}
print("| drive | " + " | ".join(f"{l} consensus / naive" for _, l in keys) + " |")
print("|---|" + "---|" * len(keys))
def num(x):  # segment errors are null on a path under 20 m
    return "n/a" if x is None else f"{x:.4f}"
for d in drives:
    print(f"| {d} | " + " | ".join(f"{num(ev[d]['consensus'][k])} / {num(ev[d]['naive'][k])}"
                                   for k, _ in keys) + " |")
print()
print("| drives | n | " + " | ".join(f"{l} consensus / naive: mean, median (consensus better in)"
                                   for _, l in keys) + " |")
print("|---|---|" + "---|" * len(keys))
groups = [("all", lambda d: True)] + [(s, lambda d, s=s: d.startswith(s + "-"))
                                      for s in ("street", "campus", "loop")] + \
         [("4 movers", lambda d: d.endswith("-4")), ("8 movers", lambda d: d.endswith("-8"))]
for name, pick in groups:
    sel = [d for d in drives if pick(d)]
    cells = []
    for k, _ in keys:
        both = [d for d in sel if None not in (ev[d]["consensus"][k], ev[d]["naive"][k])]
        if not both:
            cells.append("n/a")
            continue
        c = [ev[d]["consensus"][k] for d in both]
        n = [ev[d]["naive"][k] for d in both]
        wins = sum(a < b for a, b in zip(c, n))
        cells.append(f"{statistics.mean(c):.4f} / {statistics.mean(n):.4f}, "
                     f"{statistics.median(c):.4f} / {statistics.median(n):.4f} ({wins})")
    print(f"| {name} | {len(sel)} | " + " | ".join(cells) + " |")
PY
