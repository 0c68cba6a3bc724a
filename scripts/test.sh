#!/usr/bin/env bash
# The whole test suite: unit and integration tests in an optimised build, the fast ones and a
# short replay under valgrind memcheck, the same tests under AddressSanitizer +
# UndefinedBehaviorSanitizer, the threaded runtime under ThreadSanitizer, and
# every libFuzzer target for a bounded time.
# Tests read real captures from ../shared/data when it exists (they skip, saying so, otherwise).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
fuzz_seconds=${CNDT_FUZZ_SECONDS:-30}
bash scripts/deps.sh test

echo "== build and test (RelWithDebInfo)"
bash scripts/build.sh build/test -DCMAKE_BUILD_TYPE=RelWithDebInfo
ctest --test-dir build/test --output-on-failure -j 2

echo "== uninitialised reads under valgrind memcheck"
bash scripts/memcheck.sh build/test

echo "== build and test (ASan + UBSan)"
bash scripts/build.sh build/asan -DCMAKE_BUILD_TYPE=Debug -DCNDT_SANITIZE=address,undefined \
  -DCNDT_BUILD_BENCHMARKS=OFF
ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
  ctest --test-dir build/asan --output-on-failure -j 2 -LE slow

echo "== the threads under ThreadSanitizer"
bash scripts/build.sh build/tsan --target thread_checks -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCNDT_SANITIZE=thread -DCNDT_BUILD_BENCHMARKS=OFF
bash scripts/tsan.sh build/tsan

echo "== fuzz (${fuzz_seconds} s per target)"
bash scripts/build.sh build/fuzz --target fuzzers -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
  -DCNDT_BUILD_FUZZERS=ON -DCNDT_BUILD_TESTS=OFF -DCNDT_BUILD_BENCHMARKS=OFF
bash scripts/fuzz.sh build/fuzz "$fuzz_seconds" build/test/src/apps/cndt
echo "cndt: all test stages passed"
