#!/usr/bin/env bash
# The Cornell box end to end over pipes: build it, solve its radiosity, describe the result.
# Writes cornell_radiosity.vdb in the current folder. RES and DIRECTIONS tune size and quality.
set -euo pipefail
VDBRAD=${VDBRAD:-vdbrad}
"$VDBRAD" make cornell - --res "${RES:-64}" --quiet \
  | "$VDBRAD" solve - cornell_radiosity.vdb --directions "${DIRECTIONS:-300}" --tolerance 1e-4
"$VDBRAD" info cornell_radiosity.vdb
