#!/usr/bin/env bash
# vdbrad against Blender Cycles on the Cornell box mesh: the same mesh, camera, size and machine,
# in one script (issue 23). Prints, for each run, the wall time of the whole process (vdbrad:
# voxelize | solve | render; Cycles: start, import, sync, render) and the image error against a
# converged Cycles reference (benchmarks/cycles/image_error.py: mean |X - ref| / mean ref outside
# the light's pixels), and the reference's own noise (half the error between two seeds).
#
#   bash benchmarks/compare_cycles.sh            (needs `blender`, Debian's 3.4; ~30 min on 2 cores)
#   REF_SPP=4096 VDBRAD_RUNS="128:1000 256:3000" CYCLES_SPP="16 64" bash benchmarks/compare_cycles.sh
#   REF1=a.exr REF2=b.exr ...                     (reuse two reference renders of different seeds)
#   VDBRAD_MESH= ...                              (draw the voxels, not the mesh: voxel outlines)
set -euo pipefail
cd "$(dirname "$0")/.."
V=${VDBRAD:-build/vdbrad}
mesh=$PWD/samples/meshes/cornell_box.obj
cam="0.278,0.273,-0.8,0.278,0.273,0,0,1,0,39.3"
size=${SIZE:-320x240}
out=${OUT:-/tmp/vdbrad_vs_cycles}
mkdir -p "$out"
blender_run() {   # SAMPLES SEED OUT.exr
  blender -b -noaudio --factory-startup --python benchmarks/cycles/cornell_cycles.py -- \
    "$mesh" "$3" "$1" "$2" "$size" "$cam" > "$out/blender.log" 2>&1
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
for run in ${VDBRAD_RUNS-64:1000 128:300 128:1000 128:3000 256:1000 256:3000 512:1000}; do
  res=${run%%:*}; dirs=${run##*:}
  for direct in sweep exact; do
    img="$out/vdbrad_${res}_${dirs}_${direct}.exr"
    t=$(seconds sh -c "'$V' voxelize '$mesh' - --res $res --quiet \
      | '$V' solve - - --directions $dirs --tolerance 1e-4 --direct $direct --quiet \
      | '$V' render - '$img' --res $size --camera $cam --exr-type float --aa 4 --quiet \
        ${VDBRAD_MESH-"--mesh '$mesh'"}")
    images+=("$img"); labels+=("vdbrad res $res, $dirs directions, direct $direct: $t s")
  done
done
for spp in ${CYCLES_SPP-16 64 256 1024}; do
  img="$out/cycles_${spp}.exr"
  t=$(seconds blender_run "$spp" 7 "$img")
  images+=("$img"); labels+=("cycles $spp spp: $t s")
done
printf '%s\n' "${labels[@]}"
blender -b -noaudio --factory-startup --python benchmarks/cycles/image_error.py -- \
  --noise "$ref2" "$ref1" "${images[@]}" 2>/dev/null | grep -E "error|noise|stripes"
