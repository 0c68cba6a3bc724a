#!/usr/bin/env bash
# Configures and builds one build tree. Usage: scripts/build.sh DIR [--target T] [cmake args...]
set -euo pipefail
dir=$1; shift
target=()
if [[ "${1:-}" == "--target" ]]; then target=(--target "$2"); shift 2; fi
export CCACHE_DIR=${CCACHE_DIR:-$HOME/.cache/cndt-ccache}
cmake -S "$(dirname "$0")/.." -B "$dir" -G Ninja -DCMAKE_CXX_COMPILER_LAUNCHER=ccache "$@" >/dev/null
cmake --build "$dir" -j "$(nproc)" "${target[@]}"
