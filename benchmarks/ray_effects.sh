#!/usr/bin/env bash
# Ray effects of the reflected light (issue 23, part 2): a fixed direction set against changing
# sets between iterations, averaged solves of several sets, smoothing of the reflected part, and
# the renderer's final gather, on the Cornell box mesh at one resolution. Every variant is rendered
# like benchmarks/compare_cycles.sh (320 x 240, --aa 4, --mesh) and measured twice: against a
# solve of the same voxels with DIRS_REF directions (the direction set's error alone) and, given
# REF1/REF2, against Cycles (everything).
#
#   RES=128 REF1=ref_1.exr REF2=ref_2.exr bash benchmarks/ray_effects.sh     (~6 min at res 128)
set -euo pipefail
cd "$(dirname "$0")/.."
V=${VDBRAD:-build/vdbrad}
B=${BENCH:-build/benchmarks/bench_ray_effects}
mesh=$PWD/samples/meshes/cornell_box.obj
cam="0.278,0.273,-0.8,0.278,0.273,0,0,1,0,39.3"
res=${RES:-128}
iters=${ITERATIONS:-24}      # Jacobi: residual < 1e-7 on this box
out=${OUT:-/tmp/vdbrad_ray_effects}
mkdir -p "$out"
render() {  # SOLVED.vdb OUT.exr [render options]
  local f=$1 img=$2; shift 2
  "$V" render "$f" "$img" --res 320x240 --camera $cam --exr-type float --aa 4 --quiet \
    --mesh "$mesh" "$@"
}
seconds() { local t0=$(date +%s.%N); "$@" > /dev/null; echo "$(date +%s.%N) - $t0" | bc; }

"$V" voxelize "$mesh" "$out/scene.vdb" --res "$res" --quiet --overwrite
"$V" solve "$out/scene.vdb" "$out/reference.vdb" --directions "${DIRS_REF:-20000}" \
  --tolerance 1e-6 --quiet --overwrite
render "$out/reference.vdb" "$out/reference.exr"

images=()
run() {  # NAME MODE ARGS...: one variant, solved by bench_ray_effects
  local name=$1; shift
  "$B" "$out/scene.vdb" "$out/$name.vdb" "$iters" "$@"
  render "$out/$name.vdb" "$out/$name.exr"
  images+=("$out/$name.exr")
}
run fixed_837 fixed 800
run fixed_967 fixed 1000
run fixed_1131 fixed 1100
run fixed_2919 fixed 3000
run alternate_837_967_1131 alternate 800 1000 1100
run average_837_967_1131 average 800 1000 1100
run smooth1_967 smooth 1 1000
run smooth2_967 smooth 2 1000
for g in ${GATHER-64 256}; do
  echo "render --gather $g: $(seconds render "$out/fixed_967.vdb" "$out/gather${g}_967.exr" \
    --gather "$g") s (without: $(seconds render "$out/fixed_967.vdb" "$out/plain.exr") s)"
  images+=("$out/gather${g}_967.exr")
done

measure() {
  blender -b -noaudio --factory-startup --python benchmarks/cycles/image_error.py -- "$@" \
    "${images[@]}" 2>/dev/null | grep -E "error|noise|stripes"
}
echo "against the ${DIRS_REF:-20000}-direction solve (the direction set's error):"
measure "$out/reference.exr"
if [ -n "${REF1:-}" ]; then
  echo "against Cycles:"
  measure --noise "$REF2" "$REF1" "$out/reference.exr"
fi
