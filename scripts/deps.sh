#!/usr/bin/env bash
# Installs the Debian 12 packages cndt needs to build, test and fuzz. Runs apt only when
# something is missing. Usage: scripts/deps.sh [build|test]
set -euo pipefail
need=(cmake ninja-build g++ pkg-config libeigen3-dev libboost-dev libspdlog-dev libfmt-dev
      libpcap-dev libtomlplusplus-dev libcli11-dev libsystemd-dev libgtest-dev libgmock-dev
      libbenchmark-dev ccache)
if [[ "${1:-build}" == "test" ]]; then
  need+=(clang libclang-rt-14-dev valgrind)
fi
missing=()
for p in "${need[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "cndt: installing ${missing[*]}"
  if [[ $(id -u) -ne 0 ]]; then
    echo "cndt: these packages are missing and installing them needs root: ${missing[*]}" >&2
    exit 1
  fi
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
