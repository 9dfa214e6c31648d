#!/usr/bin/env bash
# The main job on the built-in default scene: installs the dependencies, builds vdbrad, then runs
# the whole chain on the Cornell box mesh (samples/meshes/cornell_box.obj) over pipes:
# voxelize -> solve -> render (the picture drawn on the mesh itself: exact outlines). Leaves out/cornell_box_lit.vdb, out/cornell_box.exr and
# out/cornell_box.png (VDBRAD_OUT sets the folder) and describes the solved scene.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)" --target vdbrad_cli
out=${VDBRAD_OUT:-out}
mkdir -p "$out"
./build/vdbrad voxelize samples/meshes/cornell_box.obj - --res "${VDBRAD_RES:-128}" \
  | ./build/vdbrad solve - - --directions "${VDBRAD_DIRECTIONS:-1000}" --tolerance 1e-4 \
  | tee "$out/cornell_box_lit.vdb" \
  | ./build/vdbrad render - "$out/cornell_box.exr" --png "$out/cornell_box.png" --aa 2 \
      --mesh samples/meshes/cornell_box.obj
./build/vdbrad info "$out/cornell_box_lit.vdb"
echo "main-job: wrote $out/cornell_box_lit.vdb, $out/cornell_box.exr and $out/cornell_box.png" >&2
