#!/usr/bin/env bash
# Builds the library, CLI and tests with AddressSanitizer and UndefinedBehaviorSanitizer
# (-DMODALCAL_SANITIZE=ON, into ./build-sanitize) and runs the tests outside the labels `long`,
# `heavy` and `unsanitized` (the sanitized code at -O1 runs about ten times slower; the long and
# heavy ones repeat what the others check, at a larger size or over more runs). Any sanitizer
# report fails the test that triggered it.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build-sanitize -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG="-O1 -g1" -DMODALCAL_SANITIZE=ON \
  -DMODALCAL_BUILD_BENCHMARKS=OFF >/dev/null
cmake --build build-sanitize -j"$(nproc)"
export ASAN_OPTIONS="detect_leaks=1:halt_on_error=1"
export LSAN_OPTIONS="suppressions=$PWD/tests/sanitizer/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:suppressions=$PWD/tests/sanitizer/ubsan.supp"
cd build-sanitize && ctest --output-on-failure -j"$(nproc)" -LE "long|heavy|unsanitized" --timeout 1500
