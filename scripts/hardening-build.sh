#!/usr/bin/env bash
# Configures build-hardening/, the one instrumented build that scripts/sanitize.sh (test suites)
# and scripts/fuzz.sh (libFuzzer targets) share: clang, ASan + UBSan, libFuzzer's coverage on
# the library (-DVDBRAD_FUZZ=ON), Debug (-O1 -g), no MPI (Open MPI's start-up allocations would
# read as leaks), no benchmarks. Compiling the library once for both saves an instrumented build
# of it in every CI run (two builds took ~25 of CI's ~55 minutes). Sourced by both scripts.
#
# The test suites CI can afford (measured in docs/journal/2026-12-01-hardening.md): every reader
# of untrusted input (files, meshes, command lines, through the tool itself) and each solver
# once. SANITIZE_SUITES (";"-separated suite names, or "all") overrides them.
suites=${SANITIZE_SUITES:-"test_cli;test_io;test_scene;test_mesh"}
[ "$suites" = all ] && suites=""
cmake -S . -B build-hardening -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
  -DCMAKE_BUILD_TYPE=Debug -DVDBRAD_FUZZ=ON -DVDBRAD_MPI=OFF -DVDBRAD_BUILD_BENCHMARKS=OFF \
  -DVDBRAD_BUILD_TESTS=ON -DVDBRAD_TEST_SUITES="$suites" >/dev/null
