#!/bin/bash
# A diagnosis's time against a reference build's, side by side in one run.
#
# The issue that added the stepwise loop and the spatial families bounds an LFU diagnosis at three
# times what the diagnosis of the first version took on the six cases of problems/lfu-hidden
# (17-40 s on the machine of the time). Wall times on one machine vary by 1.5x from day to day,
# so the bound is judged here as a ratio: both builds' `diagnose` run one after the other on the
# same cases in the same hour, in alternating order (reference first on odd cases, this build
# first on even ones), as a user runs them (no environment variable, one at a time).
#
# usage: bash bench/diagnosis_time_ratio.sh REFERENCE_FULLSPACE_CALIB FULLSPACE_CALIB [CASE.yaml ...]
#   REFERENCE_FULLSPACE_CALIB: the tool built at the first version (e.g. commit 72a25f1);
#   FULLSPACE_CALIB: the build to measure; CASE.yaml: further cases for both (for instance those
#   `diagnosis_benchmark --write-data DIR` writes), after the six.
# Prints per case each build's wall and CPU seconds and the ratio, then the bound: this build's
# slowest diagnosis against three times the reference's slowest on the six.
set -euo pipefail
if [ $# -lt 2 ]; then
  sed -n '/^# usage/,/^# slowest/p' "$0" >&2
  exit 2
fi
reference=$1 build=$2
shift 2
for bin in "$reference" "$build"; do
  [ -x "$bin" ] || { echo "diagnosis_time_ratio: $bin is not an executable" >&2; exit 2; }
done
# Absolute, since each diagnosis runs in its case's folder (the case's files are relative to it).
reference=$(cd "$(dirname "$reference")" && pwd)/$(basename "$reference")
build=$(cd "$(dirname "$build")" && pwd)/$(basename "$build")
here=$(cd "$(dirname "$0")/.." && pwd)
cases=()
for c in base-flexibility control joint-rotation soft-foam stiff-post top-mass; do cases+=("$here/problems/lfu-hidden/$c.yaml"); done
six=${#cases[@]}
for c in "$@"; do
  [ -r "$c" ] || { echo "diagnosis_time_ratio: cannot read $c" >&2; exit 2; }
  cases+=("$(cd "$(dirname "$c")" && pwd)/$(basename "$c")")
done
out=$(mktemp -d /tmp/diagnosis_time_ratio.XXXXXX)
echo "# $(date -u '+%Y-%m-%d %H:%M UTC'), $(nproc) cores; outputs in $out"
echo "# reference: $reference"
echo "# this build: $build"

# Runs `diagnose` of binary $1 on case $2, output under tag $3; prints "wall cpu".
run() {
  local dir times
  dir=$(dirname "$2")
  # bash's own timer: real, user and system seconds of the command and its threads
  times=$( { TIMEFORMAT='%R %U %S'; time (cd "$dir" && "$1" diagnose "$2" --json "$out/$3.json" > "$out/$3.out" \
             2> "$out/$3.err"); } 2>&1 ) || { echo "diagnosis_time_ratio: $1 failed on $2 (see $out/$3.err)" >&2; exit 1; }
  echo "$times" | awk '{printf "%.1f %.1f\n", $1, $2 + $3}'
}

printf '%-28s %18s %18s %8s\n' case "reference s (cpu)" "this build s (cpu)" ratio
rows=$out/rows
for i in "${!cases[@]}"; do
  c=${cases[$i]}
  if (( i % 2 == 0 )); then
    read -r rw rc < <(run "$reference" "$c" "ref-$i"); read -r nw nc < <(run "$build" "$c" "new-$i")
  else
    read -r nw nc < <(run "$build" "$c" "new-$i"); read -r rw rc < <(run "$reference" "$c" "ref-$i")
  fi
  echo "$(basename "$c" .yaml) $rw $rc $nw $nc $(( i < six ))" >> "$rows"
  tail -1 "$rows" | awk '{printf "%-28s %8.1f (%7.1f) %8.1f (%7.1f) %8.2f\n", $1, $2, $3, $4, $5, $4 / $2}'
done
awk '{ if ($6 && $2 > ref) ref = $2; if ($6 && $4 > six) six = $4; if ($4 > all) { all = $4; slowest = $1 } }
  END {
    printf "the reference'"'"'s slowest of the six: %.1f s; three times that: %.1f s\n", ref, 3 * ref
    printf "this build'"'"'s slowest of the six: %.1f s (%.2f of the bound)\n", six, six / (3 * ref)
    printf "this build'"'"'s slowest case: %s, %.1f s (%.2f of the bound): %s\n", slowest, all, all / (3 * ref),
           all <= 3 * ref ? "met" : "NOT met"
  }' "$rows"
