#!/usr/bin/env bash
# Installs ShineVDB's Debian 12 dependencies (when missing), builds it in Release into build/ and
# makes the Python module importable by Debian's /usr/bin/python3 (`import shinevdb`, through a
# .pth file pointing at build/python). Run as root (or with sudo available) on Debian 12.
#
#   scripts/setup.sh             builds everything: libraries, the shine CLI, the Python module,
#                                the test suite and the benchmarks (what scripts/run_tests.sh needs)
#   scripts/setup.sh --example   builds only the shine CLI and the Python module (what
#                                scripts/run_example.sh needs: a few minutes instead of many)
set -euo pipefail
cd "$(dirname "$0")/.."

only_example=0
case "${1:-}" in
    "") ;;
    --example) only_example=1 ;;
    *) echo "setup: unknown argument '$1' (expected nothing or --example)" >&2; exit 2 ;;
esac

# What building needs (the Python module included), then what only the tests and the other
# scripts need: Blender for the add-on's tests, Dask for scripts/shine_dask_tiles.py, ROS and
# compression modules to write test recordings, pytest, matplotlib for examples/python.
BUILD_PACKAGES=(cmake g++ make pkg-config
                libopenvdb-dev libopenvdb-tools libboost-iostreams-dev libtbb-dev libeigen3-dev
                libimath-dev libopenexr-dev openexr libyaml-cpp-dev nlohmann-json3-dev
                libcli11-dev libnanoflann-dev libgtest-dev libgmock-dev libbenchmark-dev
                libpng-dev libbz2-dev zlib1g-dev liblz4-dev libzstd-dev libsqlite3-dev
                python3-dev pybind11-dev python3-pybind11 python3-numpy)
TEST_PACKAGES=(blender python3-distributed python3-yaml
               python3-rosbag python3-sensor-msgs python3-roslz4 python3-lz4 python3-zstandard
               python3-pytest python3-matplotlib)
PACKAGES=("${BUILD_PACKAGES[@]}")
[ "$only_example" -eq 1 ] || PACKAGES+=("${TEST_PACKAGES[@]}")

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
if [ "$only_example" -eq 1 ]; then
    # The `example` target: the shine CLI and, when pybind11 was found (SHINE_BUILD_PYTHON), the
    # Python module, built together so that the module compiles while the CLI does.
    cmake --build build -j"$(nproc)" --target example
else
    cmake --build build -j"$(nproc)"
fi

# `import shinevdb` for /usr/bin/python3 from any directory: a .pth file in its first site
# directory (/usr/local/lib/python3.11/dist-packages) naming the build's package directory.
if compgen -G "build/python/shinevdb/_shinevdb*.so" >/dev/null; then
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
