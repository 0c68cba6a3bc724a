#!/usr/bin/env bash
# Runs every fuzz target of a fuzz build for a bounded time, seeded with a simulated capture.
# Usage: scripts/fuzz.sh FUZZ_BUILD_DIR SECONDS CNDT_BINARY
set -euo pipefail
build=$1; seconds=$2; cndt=$3
seeds="$build/seeds"
rm -rf "$seeds"; mkdir -p "$seeds/fuzz_pcap" "$seeds/fuzz_decoder" "$seeds/fuzz_frame"
"$cndt" sim --scene street --duration 0.1 --out "$seeds/sim" >/dev/null
"$cndt" sim --scene campus --duration 0.1 --dual --out "$seeds/sim-dual" >/dev/null
cp "$seeds/sim/capture.pcap" "$seeds/fuzz_pcap/single.pcap"
cp "$seeds/sim-dual/capture.pcap" "$seeds/fuzz_pcap/dual.pcap"
# One packet each: control byte, then kind 0 with a length the target steers to 1206.
for mode in sim sim-dual; do
  { printf '\x01\x00\x00\x00'; dd if="$seeds/$mode/capture.pcap" bs=1 skip=82 count=1206 2>/dev/null;
    printf '\x00\x00\x00'; dd if="$seeds/$mode/capture.pcap" bs=1 skip=$((82 + 1248 + 16)) count=1206 2>/dev/null;
  } > "$seeds/fuzz_decoder/$mode.bin"
  { printf '\x01'; dd if="$seeds/$mode/capture.pcap" bs=1 skip=40 count=1248 2>/dev/null; } \
    > "$seeds/fuzz_frame/$mode.bin"
done
for bin in "$build"/tests/fuzz/fuzz_*; do
  [[ -x "$bin" ]] || continue
  name=$(basename "$bin")
  corpus="$build/corpus/$name"
  mkdir -p "$corpus"
  echo "fuzz: $name for $seconds s"
  if ! "$bin" -max_total_time="$seconds" -print_final_stats=1 -artifact_prefix="$build/$name-" \
      "$corpus" "$seeds/$name" >"$build/$name.log" 2>&1; then
    tail -60 "$build/$name.log"
    echo "fuzz: $name found a failure; the input is in $build/$name-*" >&2
    exit 1
  fi
  grep -E "stat::number_of_executed_units|Done [0-9]+ runs" "$build/$name.log" | tail -2
done
