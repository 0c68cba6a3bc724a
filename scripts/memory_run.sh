#!/usr/bin/env bash
# Long-run memory of `cndt replay` with the mapper: simulates a street drive of SECONDS, replays
# it faster than real time with a bounded map window, and samples the process's resident memory
# (VmRSS, VmHWM) every INTERVAL seconds, placing each sample on the capture's time by the
# replay's read position in the capture file. Prints one CSV line per sample
# (capture_s,rss_mb,hwm_mb) and then the growth between two capture times.
# Usage: scripts/memory_run.sh [BUILD_DIR] [SECONDS] [WINDOW_M] [OUT_DIR]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build/release}
seconds=${2:-3600}
window=${3:-150}
out=${4:-$root/out/memory}
interval=${INTERVAL:-15}
cndt=$build/src/apps/cndt
mkdir -p "$out"
capture=$out/capture.pcap
if [[ ! -f $capture ]]; then
  "$cndt" sim --scene street --duration "$seconds" --seed 3 --movers 4 --out "$out" >/dev/null
fi
size=$(stat -c %s "$capture")
capture_path=$(realpath "$capture")
"$cndt" replay "$capture" --out "$out/run" --mapper --map-window "$window" \
  >"$out/replay.log" 2>&1 &
pid=$!
samples=$out/rss.csv
echo "capture_s,rss_mb,hwm_mb" >"$samples"
while kill -0 "$pid" 2>/dev/null; do
  sleep "$interval"
  [[ -r /proc/$pid/status ]] || break
  rss=$(awk '/^VmRSS/ {print $2}' "/proc/$pid/status" 2>/dev/null || true)
  hwm=$(awk '/^VmHWM/ {print $2}' "/proc/$pid/status" 2>/dev/null || true)
  pos=""
  for fd in /proc/$pid/fd/*; do
    if [[ $(readlink "$fd" 2>/dev/null) == "$capture_path" ]]; then
      pos=$(awk '/^pos:/ {print $2}' "/proc/$pid/fdinfo/${fd##*/}" 2>/dev/null || true)
    fi
  done
  [[ -n $rss && -n $pos ]] || continue
  awk -v p="$pos" -v s="$size" -v d="$seconds" -v r="$rss" -v h="$hwm" \
    'BEGIN { printf "%.0f,%.1f,%.1f\n", p / s * d, r / 1024, h / 1024 }' | tee -a "$samples"
done
wait "$pid"
# Growth of the resident memory from minute 10 to the end (the largest sample of each end).
python3 - "$samples" "$seconds" <<'PY'
import csv, sys
rows = [(float(r["capture_s"]), float(r["rss_mb"])) for r in csv.DictReader(open(sys.argv[1]))]
end = float(sys.argv[2])
at10 = max((m for t, m in rows if 540 <= t <= 660), default=None)
last = max((m for t, m in rows if t >= end - 120), default=None)
peak = max((m for _, m in rows), default=None)
if at10 is None or last is None:
    sys.exit("not enough samples around minute 10 and the end")
print(f"minute 10: {at10:.1f} MB, end: {last:.1f} MB, growth {100 * (last / at10 - 1):+.2f} %, "
      f"peak sampled {peak:.1f} MB")
PY
