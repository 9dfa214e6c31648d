#!/usr/bin/env bash
# A level set made by vdb_tool becomes explicit surface voxels, then is described: no temporary
# files, every step on a pipe. Writes sphere_surface.vdb in the current folder.
set -euo pipefail
VDBRAD=${VDBRAD:-vdbrad}
vdb_tool -quiet -sphere r=1 dim=64 -o stdout.vdb \
  | "$VDBRAD" surface - - --quiet \
  | tee sphere_surface.vdb \
  | "$VDBRAD" info -
