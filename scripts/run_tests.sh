#!/usr/bin/env bash
# Sets everything up and builds everything (libraries, CLI, Python module, tests, benchmarks),
# then runs the whole test suite with ctest.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup.sh
ctest --test-dir build --output-on-failure -j"$(nproc)"
