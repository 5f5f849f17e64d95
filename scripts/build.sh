#!/usr/bin/env bash
# Configures (Release) and builds everything into ./build; arguments go to CMake's configure step
# (e.g. -DMODALCAL_WARNINGS_AS_ERRORS=ON, as CI builds).
set -euo pipefail
cd "$(dirname "$0")/.."
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
cmake --build build -j"$(nproc)"
