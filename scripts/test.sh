#!/usr/bin/env bash
# Installs the dependencies (Debian packages), builds vdbrad and runs every test.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DVDBRAD_BUILD_TESTS=ON
cmake --build build -j"$(nproc)"
ctest --test-dir build --output-on-failure -j"$(nproc)"
# Hardening (docs/hardening.md): a sanitized build of the suites that read untrusted input, then
# each fuzz target for FUZZ_SECONDS. VDBRAD_HARDENING=0 skips both.
if [ "${VDBRAD_HARDENING:-1}" != 0 ]; then
  bash scripts/sanitize.sh
  bash scripts/fuzz.sh
fi
