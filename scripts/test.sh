#!/usr/bin/env bash
# The README's test command: installs what is missing, builds, and runs every test with ctest.
# Arguments go to CMake's configure step (scripts/build.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/build.sh "$@"
cd build && ctest --output-on-failure -j"$(nproc)"
