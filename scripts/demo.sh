#!/usr/bin/env bash
# The main job on a capture cndt makes itself: simulate a VLP-16 drive down a street, run the
# odometry over it and score it against the ground truth, decode the CAN frames it would send
# with config/cndt.dbc, then run the daemon cndtd on the same capture at the sensor's pace with
# the mapper on, and show the map it saved.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
bash scripts/deps.sh build
# Only the two programs the demo runs. A tree configured before (with tests or benchmarks, say)
# keeps its options; a new one leaves tests and benchmarks out.
fresh=()
[[ -f build/release/CMakeCache.txt ]] || fresh=(-DCNDT_BUILD_TESTS=OFF -DCNDT_BUILD_BENCHMARKS=OFF)
bash scripts/build.sh build/release --target cndt --target cndtd -DCMAKE_BUILD_TYPE=Release \
  "${fresh[@]}"
bin=./build/release/src/apps
out=out/demo
rm -rf "$out"
"$bin/cndt" sim --scene street --duration 10 --movers 4 --seed 1 --out "$out"
"$bin/cndt" info "$out/capture.pcap"
"$bin/cndt" decode "$out/capture.pcap" --out "$out/scans" --format pcd
"$bin/cndt" replay "$out/capture.pcap" --out "$out/replay"
"$bin/cndt" eval --gt "$out/groundtruth.tum" --est "$out/replay/trajectory.tum" > "$out/replay/eval.json"
echo "cndt demo: odometry against the ground truth:"
grep -E '"(ate_rmse_m|rte_percent|rre_deg_per_m)"' "$out/replay/eval.json"
echo "cndt demo: the first CAN frames, decoded with config/cndt.dbc:"
"$bin/cndt" listen --candump "$out/replay/can.log" --dbc config/cndt.dbc --out "$out/replay/can.csv"
head -6 "$out/replay/can.csv"
cat > "$out/cndtd.toml" <<TOML
[sensor]
source = "pcap"
pcap = "$root/$out/capture.pcap"
[mapper]
enabled = true
save = "$root/$out/map.cndtmap"
[can]
log = "$root/$out/cndtd-can.log"
[runtime]
status_interval_s = 2.0
TOML
"$bin/cndtd" --check --config "$out/cndtd.toml"
"$bin/cndtd" --config "$out/cndtd.toml" 2>&1 | grep -v '^cndtd: info:   '
"$bin/cndt" map info "$out/map.cndtmap"
echo "cndt demo: capture, ground truth, decoded scans, replay outputs, the daemon's CAN log and map are in $root/$out"
