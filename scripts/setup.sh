#!/usr/bin/env bash
# Installs vdbrad's build dependencies from Debian packages (idempotent; run as root or with sudo).
# libboost-dev / libboost-iostreams-dev: Debian 12's libopenvdb-dev needs them to compile and for
# its FindOpenVDB.cmake. libopenvdb-tools brings vdb_tool/vdb_print (interop tests), openexr brings
# exrheader, time brings /usr/bin/time (peak memory in samples/trade_study.sh). clang and
# libclang-rt-14-dev (libFuzzer and clang's sanitizer runtimes, only recommended by clang) build
# the fuzz targets (scripts/fuzz.sh); g++'s own ASan/UBSan runtimes serve scripts/sanitize.sh.
# libeigen3-dev and libglpk-dev fit glossy lobes to control points (least squares, and the
# max-norm linear programs). libopenmpi-dev and openmpi-bin distribute solves over MPI ranks
# (`mpirun -np K vdbrad solve ...`; the build does without them, the tests use them).
# pybind11-dev, libboost-python-dev and python3-dev build the Python module (python/), which takes
# and returns python3-openvdb's grids (pyopenvdb, Boost.Python) and NumPy images (python3-numpy);
# the build does without them.
set -euo pipefail
pkgs=(cmake g++ make libopenvdb-dev libopenvdb-tools libboost-dev libboost-iostreams-dev
      libopenexr-dev libglm-dev libgtest-dev openexr time clang libclang-rt-14-dev
      libeigen3-dev libglpk-dev libopenmpi-dev openmpi-bin
      pybind11-dev libboost-python-dev python3-dev python3-openvdb python3-numpy)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  echo "setup: installing ${missing[*]}" >&2
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >&2
fi
