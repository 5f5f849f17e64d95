#!/usr/bin/env bash
# Installs the Debian 12 packages the project builds with, only those missing (idempotent).
# Why each: Ipopt+MUMPS (full-space NLP), Eigen (dense/sparse containers), SuiteSparse (CHOLMOD
# supernodal Cholesky), OpenBLAS (CHOLMOD is 7-10x slower on reference BLAS), Spectra (Lanczos),
# GoogleTest, yaml-cpp (problem files with line numbers), CLI11, nlohmann-json, gnuplot (plots).
set -euo pipefail
packages=(
  g++ cmake make pkg-config
  coinor-libipopt-dev libeigen3-dev libsuitesparse-dev libopenblas-dev libspectra-dev
  libgtest-dev libyaml-cpp-dev libcli11-dev nlohmann-json3-dev gnuplot-nox
)
missing=()
for p in "${packages[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "installing: ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
