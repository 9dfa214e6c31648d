#!/usr/bin/env bash
# Builds every canonical scene at a modest resolution into ./scenes/ and describes each.
set -euo pipefail
VDBRAD=${VDBRAD:-vdbrad}
mkdir -p scenes
for name in furnace-box furnace-sphere disk plates cornell slab cumulus; do
  "$VDBRAD" make "$name" "scenes/$name.vdb" --res "${RES:-64}" --quiet
  "$VDBRAD" info "scenes/$name.vdb"
done
