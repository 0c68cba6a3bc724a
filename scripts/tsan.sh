#!/usr/bin/env bash
# The threads under ThreadSanitizer: the scoring threads' hand-offs, the live pipeline
# overloaded (drops on both sides of the rings) and idle (its threads asleep until a scan comes),
# a replay whose odometry runs ahead of a busy mapper or waits while it pauses between scans, the
# UDP receiver and its sleeping consumer, then cndtd on a short simulated capture with the
# mapper, CAN and UDP outputs and health lines every half second. Any report fails the stage
# (TSan exits non-zero), and so does a step still running after 30 minutes (a hang: `timeout`
# says so and stops it).
# Usage: scripts/tsan.sh BUILD_DIR
set -euo pipefail
build=$1
export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1"
bounded=(timeout --verbose --kill-after=30 1800)
"${bounded[@]}" "$build/tests/runtime_tests" --gtest_filter='Runtime.Live*:Runtime.ReplayOdometryRunsAhead*:Runtime.ReplayLosesNoScan*:AllocCounter.*:ScoreThreads.*'
"${bounded[@]}" "$build/tests/udp_live_tests"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$build/src/apps/cndt" sim --scene street --duration 3 --out "$tmp/sim"
cat > "$tmp/cndtd.toml" <<TOML
[sensor]
source = "pcap"
pcap = "$tmp/sim/capture.pcap"
pcap_realtime = false
[mapper]
enabled = true
save = "$tmp/map.cndtmap"
[can]
log = "$tmp/can.log"
[udp]
destinations = ["127.0.0.1:9"]
[runtime]
status_interval_s = 0.5
TOML
"${bounded[@]}" "$build/src/apps/cndtd" --config "$tmp/cndtd.toml" 2>&1 | grep -E 'final:|saved|warning:|error:|WARNING'
test -s "$tmp/map.cndtmap"
echo "cndt: no ThreadSanitizer report"
