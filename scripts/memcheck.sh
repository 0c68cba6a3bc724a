#!/usr/bin/env bash
# Reads of uninitialised memory under valgrind memcheck, which none of the sanitizer stages
# catch (MemorySanitizer would need an instrumented standard library): the unit tests, the
# mapper's test of a new voxel entering the map, and a short replay with the mapper through the
# whole pipeline. Any report fails the stage, and so does a step still running after 25 minutes
# (a hang: `timeout` says so and stops it).
# Usage: scripts/memcheck.sh BUILD_DIR (a build with tests, e.g. the RelWithDebInfo one)
set -euo pipefail
build=$1
vg=(timeout --verbose --kill-after=30 1500 valgrind -q --error-exitcode=9 --leak-check=no --track-origins=yes)
for t in vlp16_unit_tests pcap_unit_tests ndt_unit_tests output_tests config_tests slam_tests; do
  echo "cndt: memcheck $t"
  "${vg[@]}" "$build/tests/$t" --gtest_brief=1
done
echo "cndt: memcheck mapper_tests (a new voxel entering the map)"
"${vg[@]}" "$build/tests/mapper_tests" --gtest_brief=1 \
  --gtest_filter='Mapper.EveryPointOfANewVoxelEntersTheMap'
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$build/src/apps/cndt" sim --scene loop --duration 2 --out "$tmp/sim" >/dev/null
echo "cndt: memcheck a 2 s replay with the mapper"
"${vg[@]}" "$build/src/apps/cndt" replay "$tmp/sim/capture.pcap" --out "$tmp/out" \
  --save-map "$tmp/map.cndtmap" 2>&1 | grep -E 'scans in|map saved|warning:|error:|=='
test -s "$tmp/map.cndtmap"
echo "cndt: no memcheck report"
