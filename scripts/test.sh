#!/usr/bin/env bash
# The whole test suite: unit and integration tests in an optimised build, the fast ones and a
# short replay under valgrind memcheck, the same tests under AddressSanitizer +
# UndefinedBehaviorSanitizer, the threaded runtime under ThreadSanitizer, and
# every libFuzzer target for a bounded time.
# Tests read real captures from ../shared/data when it exists, or beside the checkout this one was
# cloned from (they skip, saying so, otherwise).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
fuzz_seconds=${CNDT_FUZZ_SECONDS:-30}
bash scripts/deps.sh test

# The four build trees below take about 4.8 GB and the compiler cache about 1.7 GB (a clean
# clone, measured): stop now, saying so, when the disk cannot hold what is still to be built,
# rather than in a link step minutes later.
ccache_dir=${CCACHE_DIR:-$HOME/.cache/cndt-ccache}
need_mb=7000
# (du fails on the trees not made yet, after counting the rest)
built_mb=$({ du -smc build/test build/asan build/tsan build/fuzz "$ccache_dir" 2>/dev/null || true; } |
  tail -1 | cut -f1)
free_mb=$(df -Pm . | awk 'NR == 2 {print $4}')
if ((free_mb + built_mb < need_mb)); then
  echo "cndt: the test stages need about $need_mb MB of disk for their build trees and compiler" \
    "cache; $free_mb MB are free on $(df -P . | awk 'NR == 2 {print $6}') and $built_mb MB of" \
    "them are built already: free $((need_mb - free_mb - built_mb)) MB more first" >&2
  exit 1
fi

# The real captures: $CNDT_SHARED_DATA, else ../shared/data beside this checkout, else beside
# the checkout this one was cloned from (a clean clone made elsewhere to test a change).
if [[ -z ${CNDT_SHARED_DATA:-} ]]; then
  origin=$(git remote get-url origin 2>/dev/null || true)
  origin=${origin#file://}
  for dir in "$root/../shared/data" "${origin:+$origin/../shared/data}"; do
    if [[ -n $dir && -d $dir ]]; then
      CNDT_SHARED_DATA=$(cd "$dir" && pwd)
      export CNDT_SHARED_DATA
      break
    fi
  done
fi
if [[ -n ${CNDT_SHARED_DATA:-} ]]; then
  echo "cndt: real captures from $CNDT_SHARED_DATA"
else
  echo "cndt: no folder of real captures found (../shared/data or \$CNDT_SHARED_DATA):" \
    "the tests that read them will skip"
fi

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
