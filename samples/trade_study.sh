#!/usr/bin/env bash
# The speed/accuracy trade on one scene, through the command line: a Monte Carlo reference (SAMPLES
# stored rays per voxel, then a final gather of GATHER fresh ones: ~1% noise on the Cornell box
# at the defaults, in a quarter of the memory of 1024 stored rays), then the line sweeps over
# direction counts and both line types, each compared with the reference.
# Prints CSV: scene,res,directions,lines,seconds,peak_mb,mean_rel,max_rel (wall time and peak
# memory of the whole solve command; errors as `vdbrad compare` defines them).
#
#   samples/trade_study.sh [SCENE=cornell] > trade.csv
#   RES=64 GATHER=16384 DIRECTIONS="50 100 300 1000 3000" samples/trade_study.sh disk
set -euo pipefail
VDBRAD=${VDBRAD:-vdbrad}
SCENE=${1:-cornell}
RES=${RES:-32}
SAMPLES=${SAMPLES:-256}
GATHER=${GATHER:-4096}
DIRECTIONS=${DIRECTIONS:-"50 100 300 1000"}
TIME=${TIME_COMMAND:-/usr/bin/time}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

"$VDBRAD" make "$SCENE" "$tmp/scene.vdb" --res "$RES" --quiet
"$VDBRAD" solve "$tmp/scene.vdb" "$tmp/reference.vdb" --method montecarlo --samples "$SAMPLES" \
  --gather "$GATHER" --tolerance 1e-6 --quiet
echo "scene,res,directions,lines,seconds,peak_mb,mean_rel,max_rel"
for lines in naive standard; do
  for directions in $DIRECTIONS; do
    "$TIME" -f "%e %M" -o "$tmp/time" \
      "$VDBRAD" solve "$tmp/scene.vdb" "$tmp/out.vdb" --directions "$directions" \
      --lines "$lines" --overwrite --quiet
    read -r seconds kilobytes < "$tmp/time"
    read -r _ _ _ mean _ max < <("$VDBRAD" compare "$tmp/out.vdb" "$tmp/reference.vdb")
    echo "$SCENE,$RES,$directions,$lines,$seconds,$((kilobytes / 1024)),$mean,$max"
  done
done
