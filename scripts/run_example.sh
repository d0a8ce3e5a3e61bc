#!/usr/bin/env bash
# Sets up what the example needs (Debian packages, the shine CLI and the Python module; the test
# suite is built by scripts/run_tests.sh), then maps the bundled example street (simulated on
# first use into examples/street/) into out/map.vdb, out/surface.vdb and out/mesh.ply and prints
# its accuracy. Extra arguments go to `shine map` (e.g. --leaf-size-m 0.1).
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup.sh --example
./build/shine map -o out "$@"
