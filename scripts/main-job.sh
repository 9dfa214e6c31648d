#!/usr/bin/env bash
# The main job on the built-in default scene: installs the dependencies, builds vdbrad, builds the
# Cornell box, solves its radiosity and describes the result. Outputs go to out/ (VDBRAD_OUT).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)" --target vdbrad_cli
out=${VDBRAD_OUT:-out}
mkdir -p "$out"
./build/vdbrad make cornell "$out/cornell.vdb" --res "${VDBRAD_RES:-128}"
./build/vdbrad solve "$out/cornell.vdb" "$out/cornell_radiosity.vdb" \
  --directions "${VDBRAD_DIRECTIONS:-300}" --tolerance 1e-4
./build/vdbrad info "$out/cornell_radiosity.vdb"
echo "main-job: wrote $out/cornell.vdb and $out/cornell_radiosity.vdb" >&2
