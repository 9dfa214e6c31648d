#!/usr/bin/env bash
# Installs the dependencies (Debian packages), builds vdbrad and runs every test.
set -euo pipefail
cd "$(dirname "$0")/.."
# Each step's wall time on stderr: where CI's minutes go.
step() { echo "test.sh: $1 done at +$SECONDS s" >&2; }
bash scripts/setup.sh
step setup
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DVDBRAD_BUILD_TESTS=ON
cmake --build build -j"$(nproc)"
step build
ctest --test-dir build --output-on-failure -j"$(nproc)"
step tests
# Hardening (docs/hardening.md): a sanitized build of the suites that read untrusted input, then
# each fuzz target for FUZZ_SECONDS. VDBRAD_HARDENING=0 skips both.
if [ "${VDBRAD_HARDENING:-1}" != 0 ]; then
  bash scripts/sanitize.sh
  step sanitized
  bash scripts/fuzz.sh
  step fuzzing
fi
