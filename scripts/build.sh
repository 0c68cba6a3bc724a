#!/usr/bin/env bash
# Configures and builds one build tree. Usage: scripts/build.sh DIR [--target T]... [cmake args...]
set -euo pipefail
dir=$1; shift
target=()
while [[ "${1:-}" == "--target" ]]; do target+=(--target "$2"); shift 2; done
export CCACHE_DIR=${CCACHE_DIR:-$HOME/.cache/cndt-ccache}
# Paths inside the checkout are hashed relative to it (and the build directory is not hashed),
# so a fresh clone elsewhere reuses what an earlier clone compiled.
root=$(cd "$(dirname "$0")/.." && pwd)
export CCACHE_BASEDIR=${CCACHE_BASEDIR:-$root}
export CCACHE_NOHASHDIR=${CCACHE_NOHASHDIR:-1}
cmake -S "$root" -B "$dir" -G Ninja -DCMAKE_CXX_COMPILER_LAUNCHER=ccache "$@" >/dev/null
cmake --build "$dir" -j "$(nproc)" "${target[@]}"
