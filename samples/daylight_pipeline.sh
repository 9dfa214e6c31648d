#!/usr/bin/env bash
# A scene with no lamp, lit by daylight: the sun (its first collision exact, soft shadows) and
# Preetham's clear sky for its position (blue overhead, paler and brighter round the sun; in
# kcd/m^2 as Preetham's paper gives it, so a clear day's sun is ~100 klx), over pipes:
#   vdbrad voxelize blocks.obj - | vdbrad solve - - --sky-model clear --sun 50,30 \
#     --irradiance 100 | vdbrad render - blocks.exr --png blocks.png
# Then a cumulus under the same sun and sky. Writes blocks.obj (three blocks on a ground, metres,
# y up), blocks_lit.vdb, blocks.exr, blocks.png, cumulus_lit.vdb, cumulus.exr and cumulus.png in
# the current folder. RES (voxels along the longest axis) and SIZE (image WxH)
# trade quality for time.
set -euo pipefail
VDBRAD=${VDBRAD:-vdbrad}
# An axis-aligned box as 6 quads, from its low and high corners (OBJ indices continue).
box() {
  local x0=$1 y0=$2 z0=$3 x1=$4 y1=$5 z1=$6 o=$7
  printf 'v %s %s %s\n' "$x0" "$y0" "$z0" "$x1" "$y0" "$z0" "$x1" "$y1" "$z0" "$x0" "$y1" "$z0" \
    "$x0" "$y0" "$z1" "$x1" "$y0" "$z1" "$x1" "$y1" "$z1" "$x0" "$y1" "$z1"
  local f
  for f in "1 4 3 2" "5 6 7 8" "1 2 6 5" "4 8 7 3" "1 5 8 4" "2 3 7 6"; do
    set -- $f
    echo "f $(($1 + o)) $(($2 + o)) $(($3 + o)) $(($4 + o))"
  done
}
{
  echo "# a ground and three blocks, lit by no lamp"
  printf 'v -6 0 -6\nv 6 0 -6\nv 6 0 6\nv -6 0 6\nf 1 4 3 2\n'
  box -3 0 -2 -1 4 0 4
  box 0 0 -1 2 2 1 12
  box 1 0 2 4 3 4 20
} > blocks.obj
"$VDBRAD" voxelize blocks.obj - --res "${RES:-192}" --quiet 2>/dev/null \
  | "$VDBRAD" solve - - --sky-model clear --sun 50,30 --irradiance 100 --quiet \
  | tee blocks_lit.vdb \
  | "$VDBRAD" render - blocks.exr --png blocks.png --res "${SIZE:-640x480}" --quiet \
      --camera 9,8,-11,0,1,0,0,1,0,40
# A cloud under the same daylight: the sun's beam, the sky entering the box from every side and
# a ground of albedo 0.3 under it (the clear sky's ground below the horizon too); the render
# shows the sky behind it.
"$VDBRAD" make cumulus - --res "${RES:-64}" --quiet \
  | "$VDBRAD" solve-cloud - cumulus_lit.vdb --sky-model clear --sun 50,30 --irradiance 100 \
      --ground-albedo 0.3 --quiet
"$VDBRAD" render cumulus_lit.vdb cumulus.exr --png cumulus.png --res "${SIZE:-640x480}" --quiet \
  --camera 0.5,1.2,-0.9,0.5,0.3,0.5,0,1,0,45
echo "daylight_pipeline: blocks.obj -> blocks_lit.vdb, blocks.exr, blocks.png;" \
  "cumulus_lit.vdb, cumulus.exr, cumulus.png" >&2
