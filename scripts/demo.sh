#!/usr/bin/env bash
# The main job on a capture cndt makes itself: simulate a VLP-16 drive down a street, then show
# what is in the capture and decode it into per-scan point clouds.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
bash scripts/deps.sh build
bash scripts/build.sh build/release -DCMAKE_BUILD_TYPE=Release -DCNDT_BUILD_TESTS=OFF \
  -DCNDT_BUILD_BENCHMARKS=OFF
out=out/demo
rm -rf "$out"
./build/release/src/apps/cndt sim --scene street --duration 10 --movers 4 --seed 1 --out "$out"
./build/release/src/apps/cndt info "$out/capture.pcap"
./build/release/src/apps/cndt decode "$out/capture.pcap" --out "$out/scans" --format pcd
echo "cndt demo: capture, ground truth and decoded scans are in $root/$out"
