#!/usr/bin/env bash
# Installs ShineVDB's Debian 12 dependencies (when missing), builds it in Release into build/ and
# makes the Python module importable by Debian's /usr/bin/python3 (`import shinevdb`, through a
# .pth file pointing at build/python). Run as root (or with sudo available) on Debian 12.
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(cmake g++ make pkg-config
          libopenvdb-dev libopenvdb-tools libboost-iostreams-dev libtbb-dev libeigen3-dev
          libimath-dev libopenexr-dev openexr libyaml-cpp-dev nlohmann-json3-dev libcli11-dev
          libnanoflann-dev libgtest-dev libgmock-dev libbenchmark-dev
          libpng-dev libbz2-dev zlib1g-dev liblz4-dev libzstd-dev libsqlite3-dev
          blender python3-distributed python3-numpy python3-yaml
          python3-rosbag python3-sensor-msgs python3-roslz4 python3-lz4 python3-zstandard
          python3-dev pybind11-dev python3-pybind11 python3-pytest python3-matplotlib)

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

# `import shinevdb` for /usr/bin/python3 from any directory: a .pth file in its first site
# directory (/usr/local/lib/python3.11/dist-packages) naming the build's package directory.
if [ -d build/python/shinevdb ]; then
    SUDO=""
    [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    site_dir="$(/usr/bin/python3 -c 'import site; print(site.getsitepackages()[0])')"
    $SUDO mkdir -p "$site_dir"
    # Debian's Blender runs this same Python 3.11 and reads the same .pth files, and its add-on
    # is also called shinevdb: the module's folder joins sys.path everywhere but in Blender.
    echo "import os, sys; os.path.basename(sys.argv[0] if sys.argv else '').startswith('blender') or sys.path.append('$(pwd)/build/python')" |
        $SUDO tee "$site_dir/shinevdb.pth" >/dev/null
    /usr/bin/python3 -c "import shinevdb" && echo "setup: import shinevdb works ($site_dir/shinevdb.pth)"
fi
