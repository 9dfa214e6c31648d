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
#   VDBRAD_DIRECT=exact VDBRAD_SOLVE="--lines standard" ...   (one direct mode; more solve options)
#   CSV=docs/cornell-vs-cycles.csv ...            (append one row per run: scripts/plot-cycles.py)
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
rows=()   # tool,res,directions,direct,options,spp,seconds
for run in ${VDBRAD_RUNS-64:1000 128:300 128:1000 128:3000 256:1000 256:3000 512:1000}; do
  res=${run%%:*}; dirs=${run##*:}
  for direct in ${VDBRAD_DIRECT-sweep exact}; do
    tag=$(echo "${VDBRAD_SOLVE-}" | tr -c 'a-zA-Z0-9.\n-' _)
    img="$out/vdbrad_${res}_${dirs}_${direct}${tag}.exr"
    t=$(seconds sh -c "'$V' voxelize '$mesh' - --res $res --quiet \
      | '$V' solve - - --directions $dirs --tolerance 1e-4 --direct $direct --quiet \
        ${VDBRAD_SOLVE-} \
      | '$V' render - '$img' --res $size --camera $cam --exr-type float --aa 4 --quiet \
        ${VDBRAD_MESH-"--mesh '$mesh'"}")
    images+=("$img"); labels+=("vdbrad res $res, $dirs directions, direct $direct ${VDBRAD_SOLVE-}: $t s")
    rows+=("vdbrad,$res,$dirs,$direct,${VDBRAD_SOLVE-},,$t")
  done
done
for spp in ${CYCLES_SPP-16 64 256 1024}; do
  img="$out/cycles_${spp}.exr"
  t=$(seconds blender_run "$spp" 7 "$img")
  images+=("$img"); labels+=("cycles $spp spp: $t s")
  rows+=("cycles,,,,,$spp,$t")
done
printf '%s\n' "${labels[@]}"
blender -b -noaudio --factory-startup --python benchmarks/cycles/image_error.py -- \
  --noise "$ref2" "$ref1" "${images[@]}" 2>/dev/null | grep -E "error|noise|stripes" \
  | tee "$out/errors.txt"
if [ -n "${CSV-}" ]; then
  [ -s "$CSV" ] || echo "tool,res,directions,direct,options,spp,seconds,error,interior,stripes" > "$CSV"
  # image_error.py prints "IMAGE: error E interior I stripes S" in the images' order.
  grep -E "^[^ ]+: error" "$out/errors.txt" | awk '{print $3","$5","$7}' \
    | paste -d, <(printf '%s\n' "${rows[@]}") - >> "$CSV"
fi
