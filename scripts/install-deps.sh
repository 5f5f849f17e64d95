#!/usr/bin/env bash
# Installs the Debian 12 packages the project builds with, only those missing (idempotent).
# Why each: Ipopt+MUMPS (full-space NLP; MUMPS also directly, for the block Newton solver), Eigen (dense/sparse containers), SuiteSparse (CHOLMOD
# supernodal Cholesky), OpenBLAS (CHOLMOD is 7-10x slower on reference BLAS), Spectra (Lanczos),
# GoogleTest, yaml-cpp (problem files with line numbers), CLI11, nlohmann-json, gnuplot (plots),
# VTK's Python module and NumPy, which its numpy_support needs (the test that reads the VTU files
# back with an independent reader),
# Gmsh and Exodus II (reading .msh and Exodus meshes; the gmsh program turns a .geo into a .msh),
# Open MPI (campaign, study and diagnose share their calibrations among an MPI job's ranks; the
# suite runs them with mpirun).
# With MODALCAL_WITH_ROL=1 also Trilinos ROL (header-only) and the Teuchos/Kokkos libraries it
# links, for the seed-optimizer baseline (cmake -DMODALCAL_WITH_ROL=ON); the default build does
# not need them.
set -euo pipefail
packages=(
  g++ cmake make pkg-config
  coinor-libipopt-dev libmumps-seq-dev libeigen3-dev libsuitesparse-dev libopenblas-dev libspectra-dev
  libgtest-dev libyaml-cpp-dev libcli11-dev nlohmann-json3-dev gnuplot-nox python3-vtk9 python3-numpy
  libgmsh-dev gmsh libexodusii-dev libopenmpi-dev openmpi-bin
)
packages+=("$@")  # what a caller needs beside them (scripts/fuzz.sh: clang and its fuzzer runtime)
if [ "${MODALCAL_WITH_ROL:-0}" = 1 ]; then
  packages+=(libtrilinos-rol-dev libtrilinos-teuchos-dev libtrilinos-kokkos-dev)
fi
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
