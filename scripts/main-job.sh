#!/usr/bin/env bash
# The main job on the built-in default scene: installs the dependencies, builds vdbrad, builds the
# Cornell box and describes it. Outputs go to out/ (override with VDBRAD_OUT).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)" --target vdbrad_cli
out=${VDBRAD_OUT:-out}
mkdir -p "$out"
./build/vdbrad make cornell "$out/cornell.vdb" --res "${VDBRAD_RES:-128}"
./build/vdbrad info "$out/cornell.vdb"
echo "main-job: wrote $out/cornell.vdb" >&2
