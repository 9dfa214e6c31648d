#!/usr/bin/env bash
# vdbrad against Blender Cycles on the Cornell box mesh (or another one in its frame: MESH): the
# same mesh, camera, size and machine, in one script (issues 23, 25). Prints, for each run, the
# wall time of the whole process (vdbrad: voxelize | solve | render; Cycles: start, import, sync,
# render) and the image error against a converged Cycles reference (benchmarks/cycles/
# image_error.py: mean |X - ref| / mean ref outside the light's pixels), and the reference's own
# noise (half the error between two seeds).
#
#   bash benchmarks/compare_cycles.sh            (needs `blender`, Debian's 3.4; ~30 min on 2 cores)
#   REF_SPP=4096 VDBRAD_RUNS="128:1000 256:3000" CYCLES_SPP="16 64" bash benchmarks/compare_cycles.sh
#   REF1=a.exr REF2=b.exr ...                     (reuse two reference renders of different seeds)
#   VDBRAD_MESH= ...                              (draw the voxels, not the mesh: voxel outlines)
#   VDBRAD_DIRECT=exact VDBRAD_SOLVE="--lines standard" ...   (one direct mode; more solve options)
#   CSV=docs/cornell-vs-cycles.csv ...            (append one row per run: scripts/plot-cycles.py)
#   MESH=samples/meshes/glossy_cornell.obj ...    (the glossy Cornell box; output in
#       /tmp/vdbrad_vs_cycles_glossy_cornell: vdbrad solves with --brdf ggx unless VDBRAD_SOLVE
#       names a --brdf, Cycles renders Kd + Ks multiscatter GGX, cycles/cornell_cycles.py)
#   VDBRAD_RENDER="--glossy-rays 64" ...          (more render options; VDBRAD_SOLVE="--brdf ggx
#       --control-points 642" for finer lobes)
#   WORLD="--sky 1" LAMPS=off ...                 (light from outside, issue 45: vdbrad's solve
#       options --sky, --sky-model clear, --environment, --sun and theirs, the same world in
#       Cycles (cycles/cornell_cycles.py); LAMPS=off: the MTL's Ke read as 0, a copy of the mesh
#       in OUT; output in /tmp/vdbrad_vs_cycles_NAME_world unless OUT is given; a --sun runs
#       direct exact only; the references in OUT are reused: a new WORLD wants a new OUT)
#   MESH=samples/meshes/bunny.obj CAMERA=0,0.25,-0.5,0,0.05,0,0,1,0,35 \
#     WORLD="--sky-model clear --sun 45,30 --irradiance 100 --ground-albedo 0" ...
#                                                 (the Stanford bunny under sun + sky, issue 45)
set -euo pipefail
# MESH: relative to the caller's directory, else to the repository's.
mesh=${MESH:-}
[ -z "$mesh" ] || [ ! -e "$mesh" ] || mesh=$(cd "$(dirname "$mesh")" && pwd)/$(basename "$mesh")
cd "$(dirname "$0")/.."
V=${VDBRAD:-build/vdbrad}
mesh=${mesh:-samples/meshes/cornell_box.obj}
[ "${mesh:0:1}" = / ] || mesh=$PWD/$mesh
[ -e "$mesh" ] || { echo "no mesh $mesh" >&2; exit 1; }
name=$(basename "$mesh" .obj)
# A mesh whose MTL has a glossy lobe (Ks > 0): vdbrad's GGX, the lobe Cycles renders.
mtl=$(dirname "$mesh")/$(sed -n 's/^mtllib[[:space:]]*//p' "$mesh" | head -1 | tr -d '\r')
solve_opts=${VDBRAD_SOLVE-}
if [ -f "$mtl" ] && awk 'tolower($1) == "ks" { for (i = 2; i <= 4 && i <= NF; ++i)
       if ($i + 0 > 0) glossy = 1 } END { exit !glossy }' "$mtl" \
   && ! grep -q -- --brdf <<< "$solve_opts"; then
  solve_opts="--brdf ggx${solve_opts:+ $solve_opts}"
fi
cam=${CAMERA:-0.278,0.273,-0.8,0.278,0.273,0,0,1,0,39.3}
size=${SIZE:-320x240}
default_out=/tmp/vdbrad_vs_cycles
[ "$name" = cornell_box ] || default_out=${default_out}_$name   # not the box's references
[ -z "${WORLD-}" ] || default_out=${default_out}_world
out=${OUT:-$default_out}
mkdir -p "$out"
if [ "${LAMPS-}" = off ]; then
  # The mesh and its MTL copied with every Ke 0: lit from outside alone.
  cp "$mesh" "$out/$name.obj"
  sed -E 's/^([[:space:]]*)Ke .*/\1Ke 0 0 0/' "$mtl" > "$out/$(basename "$mtl")"
  mesh=$out/$name.obj
fi
solve_opts="$solve_opts${WORLD:+ $WORLD}"
# A sun (--sun) is computed exactly only: no `--direct sweep` run unless VDBRAD_DIRECT asks.
directs=${VDBRAD_DIRECT-sweep exact}
[ -n "${VDBRAD_DIRECT+set}" ] || ! grep -q -- '--sun' <<< "${WORLD-}" || directs=exact
# Below the horizon vdbrad's clear sky is a ground of --ground-albedo (default 0.2), Blender's
# Preetham texture the horizon repeated: the worlds agree there for --ground-albedo 0 only.
if grep -q -- '--sky-model clear' <<< "${WORLD-}" \
   && ! grep -qE -- '--ground-albedo 0(\.0*)?( |$)' <<< "$WORLD"; then
  echo "warning: WORLD's clear sky without --ground-albedo 0: Cycles repeats the horizon below" \
    "it, vdbrad shows a ground (background pixels and light from below differ)" >&2
fi
blender_run() {   # SAMPLES SEED OUT.exr
  WORLD=${WORLD-} blender -b -noaudio --factory-startup \
    --python benchmarks/cycles/cornell_cycles.py -- "$mesh" "$3" "$1" "$2" "$size" "$cam" \
    > "$out/blender.log" 2>&1
}
seconds() { local t0=$(date +%s.%N); "$@"; echo "$(date +%s.%N) - $t0" | bc; }

ref1=${REF1:-$out/ref_1.exr}
ref2=${REF2:-$out/ref_2.exr}
for s in 1 2; do
  f=$([ $s = 1 ] && echo "$ref1" || echo "$ref2")
  [ -e "$f" ] || { echo "reference seed $s: $(seconds blender_run "${REF_SPP:-8192}" $s "$f") s" >&2; }
done

images=()
labels=()
rows=()   # tool,res,directions,direct,options,spp,seconds
for run in ${VDBRAD_RUNS-64:1000 128:300 128:1000 128:3000 256:1000 256:3000 512:1000}; do
  res=${run%%:*}; dirs=${run##*:}
  for direct in $directs; do
    opts=$solve_opts${VDBRAD_RENDER:+ $VDBRAD_RENDER}
    tag=$(echo "$opts" | tr -c 'a-zA-Z0-9.\n-' _)
    img="$out/vdbrad_${res}_${dirs}_${direct}${tag}.exr"
    rm -f "$img"
    t=$(seconds sh -c "'$V' voxelize '$mesh' - --res $res --quiet \
      | '$V' solve - - --directions $dirs --tolerance 1e-4 --direct $direct --quiet \
        $solve_opts \
      | '$V' render - '$img' --res $size --camera $cam --exr-type float --aa 4 --quiet \
        ${VDBRAD_MESH-"--mesh '$mesh'"} ${VDBRAD_RENDER-}")
    [ -s "$img" ] || { echo "vdbrad res $res, $dirs directions, direct $direct failed" >&2; exit 1; }
    images+=("$img"); labels+=("vdbrad res $res, $dirs directions, direct $direct $opts: $t s")
    rows+=("vdbrad,$res,$dirs,$direct,${opts//,/;},,$t")   # options' commas would split columns
  done
done
for spp in ${CYCLES_SPP-16 64 256 1024}; do
  img="$out/cycles_${spp}.exr"
  t=$(seconds blender_run "$spp" 7 "$img")
  images+=("$img"); labels+=("cycles $spp spp: $t s")
  rows+=("cycles,,,,,$spp,$t")
done
printf '%s\n' "${labels[@]}"
# A daylit scene has no lamp in view: its brightest pixels count; a uniform sky seen past the
# scene (pi L in both images) does not.
sky=$(sed -nE 's/.*--sky ([0-9.e+-]+(,[0-9.e+-]+,[0-9.e+-]+)?).*/\1/p' <<< "${WORLD-}")
[ -z "$sky" ] || sky=$(python3 -c "import math, sys; v = [float(x) * math.pi for x in \
  sys.argv[1].split(',')]; print(','.join(map(repr, v * 3 if len(v) == 1 else v)))" "$sky")
BACKGROUND=${BACKGROUND:-$sky} LIGHT_MASK=${LIGHT_MASK:-$([ -n "${WORLD-}" ] && echo off || echo on)} \
  blender -b -noaudio --factory-startup --python benchmarks/cycles/image_error.py -- \
  --noise "$ref2" "$ref1" "${images[@]}" 2>/dev/null | grep -E "error|noise|stripes" \
  | tee "$out/errors.txt"
if [ -n "${CSV-}" ]; then
  [ -s "$CSV" ] || echo "tool,res,directions,direct,options,spp,seconds,error,interior,stripes" > "$CSV"
  # image_error.py prints "IMAGE: error E interior I stripes S" in the images' order.
  grep -E "^[^ ]+: error" "$out/errors.txt" | awk '{print $3","$5","$7}' \
    | paste -d, <(printf '%s\n' "${rows[@]}") - >> "$CSV"
fi
