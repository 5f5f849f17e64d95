#!/usr/bin/env bash
# Fuzzes the readers of untrusted files with libFuzzer (docs/fuzzing.md):
#   bash scripts/fuzz.sh [TARGET|all] [EXECUTIONS]     (default: all targets, 1000000 executions each)
# TARGET is a name in fuzz/targets.txt (problem, uff, gmsh, exodus, csv). Installs what is missing
# (the project's packages, clang and its libFuzzer runtime, llvm-symbolizer for the stacks),
# configures and builds ./build-fuzz with clang (-DMODALCAL_FUZZ=ON: ASan + UBSan + libFuzzer), then
# runs each target (inputs up to 16 kB: the few large seeds, such as a 3.7 MB universal file, are cut
# there, or every mutation would be that large) from the repository's files of its kind (fuzz/targets.txt) and its
# fuzz/regressions/<target>/ inputs, with a 1 s timeout per input and a 2 GB memory limit.
# The corpus a run grows is kept in build-fuzz/fuzz-corpus/<target>/ for the next run; a crashing,
# leaking or hanging input is written to build-fuzz/fuzz-artifacts/<target>/ and the script exits 1.
set -euo pipefail
cd "$(dirname "$0")/.."
target=${1:-all}
runs=${2:-1000000}

bash scripts/install-deps.sh clang libclang-rt-dev llvm

all_targets=$(grep '^[a-z]' fuzz/targets.txt | cut -d' ' -f1)
if [ "$target" = all ]; then
  targets=$all_targets
elif grep -qx "$target" <<<"$all_targets"; then
  targets=$target
else
  echo "unknown fuzz target '$target'; known: all" $all_targets >&2
  exit 2
fi

launcher=()
if command -v ccache >/dev/null; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" \
  -DCMAKE_CXX_COMPILER=clang++ -DMODALCAL_FUZZ=ON -DMODALCAL_BUILD_TESTS=OFF -DMODALCAL_BUILD_BENCHMARKS=OFF \
  "${launcher[@]}" >/dev/null
# shellcheck disable=SC2046
cmake --build build-fuzz -j"$(nproc)" --target $(printf 'fuzz_%s ' $targets)

export ASAN_OPTIONS="detect_leaks=1:halt_on_error=1"
export LSAN_OPTIONS="suppressions=$PWD/tests/sanitizer/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:suppressions=$PWD/tests/sanitizer/ubsan.supp"
failed=()
for t in $targets; do
  # The seeds: the repository's files with the target's endings (outside .git and build folders),
  # named by their paths, and the kept regressions.
  seeds=build-fuzz/fuzz-seeds/$t corpus=build-fuzz/fuzz-corpus/$t artifacts=build-fuzz/fuzz-artifacts/$t
  rm -rf "$seeds" && mkdir -p "$seeds" "$corpus" "$artifacts"
  read -r -a endings <<<"$(grep "^$t " fuzz/targets.txt | cut -d' ' -f2-)"
  name_test=()
  for e in "${endings[@]}"; do name_test+=(-o -name "*$e"); done
  find . \( -name .git -o -name 'build*' \) -prune -o -type f \( "${name_test[@]:1}" \) -print |
    while read -r f; do cp "$f" "$seeds/$(echo "${f#./}" | tr / _)"; done
  cp fuzz/regressions/"$t"/* "$seeds"/ 2>/dev/null || true
  echo "== fuzz_$t: $(ls "$seeds" | wc -l) seed files, $runs executions"
  log=build-fuzz/fuzz-$t.log
  if build-fuzz/bin/fuzz_"$t" "$corpus" "$seeds" -runs="$runs" -timeout=1 -rss_limit_mb=2048 -max_len=16384 \
      -artifact_prefix="$artifacts/" -print_final_stats=1 >"$log" 2>&1; then
    grep -E '^(Done|stat::)' "$log" || true
  else
    failed+=("$t")
    tail -n 60 "$log"
  fi
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzzing found a problem in: ${failed[*]} (inputs in build-fuzz/fuzz-artifacts/, logs build-fuzz/fuzz-*.log)"
  exit 1
fi
echo "fuzzing: no crash, leak or hang in: $targets"
