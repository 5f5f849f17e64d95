#!/usr/bin/env bash
# The README's first command: installs what is missing, builds, and runs the main job on the
# bundled LFU problem (full space, Ipopt on the structured KKT solver: 20-45 s and
# 1.6 GB on 2 cores, depending on the CPU).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/build.sh
mkdir -p out
./build/bin/fullspace_calib calibrate problems/lfu/synthetic.yaml --json out/lfu-synthetic-calibration.json
