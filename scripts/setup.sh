#!/usr/bin/env bash
# Installs ShineVDB's Debian 12 dependencies (when missing) and builds it in Release into build/.
# Run as root (or with sudo available) on Debian 12.
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(cmake g++ make pkg-config
          libopenvdb-dev libopenvdb-tools libboost-iostreams-dev libtbb-dev libeigen3-dev
          libimath-dev libopenexr-dev openexr libyaml-cpp-dev nlohmann-json3-dev libcli11-dev
          libnanoflann-dev libgtest-dev libgmock-dev libbenchmark-dev
          libpng-dev blender python3-distributed python3-numpy python3-yaml)

missing=()
for p in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    echo "setup: installing ${missing[*]}"
    SUDO=""
    [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DSHINE_BUILD_BENCHMARKS=ON
cmake --build build -j"$(nproc)"
