#!/usr/bin/env bash
# A campaign's wall time alone and across MPI ranks, side by side in one run: the same data sets
# calibrated by `campaign` in one process, then under `mpirun -np R` for each R given (rank 0
# hands out the work, so R ranks have R - 1 calibrating). Prints each time and its ratio to the
# serial one, and checks that every run's JSON summary equals the serial one.
#
#   bash bench/mpi_campaign_benchmark.sh [PROBLEM] [DATA_SETS] [RANKS...]
#   defaults: problems/portal-frame/synthetic.yaml, 8 data sets, ranks 2 3
#
# The data sets are made by synth from PROBLEM (seeds 1..DATA_SETS, 0.2 % frequency and 2 % shape
# noise) into a scratch folder. One BLAS thread per process throughout.
set -euo pipefail
cd "$(dirname "$0")/.."
problem=${1:-problems/portal-frame/synthetic.yaml}
sets=${2:-8}
shift $(( $# > 2 ? 2 : $# ))
ranks=("$@")
[ ${#ranks[@]} -gt 0 ] || ranks=(2 3)
cli=build/bin/fullspace_calib
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export OPENBLAS_NUM_THREADS=1 OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
mkdir -p "$work/data"
for s in $(seq 1 "$sets"); do
  "$cli" synth "$problem" --noise-freq 0.002 --noise-shape 0.02 --seed "$s" -o "$work/data/set$(printf %03d "$s").yaml" >/dev/null
done

calc() { python3 -c "print($1)"; }
seconds() { local t0 t1; t0=$(date +%s.%N); "$@" >/dev/null; t1=$(date +%s.%N); calc "$t1 - $t0"; }
summary() { python3 -c 'import json,sys; print(json.dumps(json.load(open(sys.argv[1]))["summary"], sort_keys=True))' "$1"; }

echo "# $problem, $sets data sets, $(nproc) cores, commit $(git rev-parse --short HEAD), $(date -u +%F)"
serial=$(seconds "$cli" campaign "$problem" "$work/data" --json "$work/serial.json")
printf "%-22s %9.1f s  %5.2fx\n" "1 process" "$serial" 1
for r in "${ranks[@]}"; do
  t=$(seconds mpirun --oversubscribe -np "$r" "$cli" campaign "$problem" "$work/data" --json "$work/mpi$r.json")
  same=$([ "$(summary "$work/serial.json")" = "$(summary "$work/mpi$r.json")" ] && echo "same summary" || echo "SUMMARY DIFFERS")
  printf "%-22s %9.1f s  %5.2fx  %s\n" "mpirun -np $r ($((r - 1)) at work)" "$t" "$(calc "$serial / $t")" "$same"
done
