#!/usr/bin/env bash
# Meshes to pictures over pipes: voxelize an OBJ (or PLY) scene, solve its radiosity, render it:
#   vdbrad voxelize in.obj - | vdbrad solve - - | vdbrad render - out.exr --png out.png
# Usage: mesh_pipeline.sh [MESH...]  (default: both sample scenes in samples/meshes/). Writes
# NAME_lit.vdb, NAME.exr and NAME.png per mesh in the current folder. RES (voxels along the
# longest axis), DIRECTIONS and SIZE (image WxH) trade quality for time.
set -euo pipefail
VDBRAD=${VDBRAD:-vdbrad}
here=$(cd "$(dirname "$0")" && pwd)
[ $# -gt 0 ] || set -- "$here/meshes/cornell_box.obj" "$here/meshes/furnished_room.obj"
for mesh in "$@"; do
  name=$(basename "${mesh%.*}")
  "$VDBRAD" voxelize "$mesh" - --res "${RES:-128}" --quiet \
    | "$VDBRAD" solve - - --directions "${DIRECTIONS:-300}" --tolerance 1e-4 --quiet \
    | tee "${name}_lit.vdb" \
    | "$VDBRAD" render - "$name.exr" --png "$name.png" --res "${SIZE:-640x480}" --quiet
  echo "mesh_pipeline: $mesh -> ${name}_lit.vdb, $name.exr, $name.png" >&2
done
