#!/usr/bin/env bash
# The README's first command: installs what is missing, builds, and runs the main job on the
# bundled LFU problem (full space, Ipopt on the structured KKT solver: about 20 s and
# 2 GB on 2 cores).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/build.sh
mkdir -p out
./build/bin/fullspace_calib calibrate problems/lfu/synthetic.yaml --json out/lfu-synthetic-calibration.json
