#!/usr/bin/env bash
# Speed of two builds of the tool on the same workloads, alternated on one machine, best of
# ROUNDS runs each: a restructuring must not slow the sweeps. Prints each workload's seconds and
# the ratio new / old, and checks the outputs are the same bits.
#   benchmarks/compare_builds.sh OLD_BUILD NEW_BUILD [ROUNDS=3]
set -euo pipefail
old=$1/vdbrad new=$2/vdbrad rounds=${3:-3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$new" make cornell "$work/cornell.vdb" --res 160 --quiet
"$new" make cumulus "$work/cumulus.vdb" --res 64 --quiet
"$new" make slab "$work/slab.vdb" --res 32 --quiet
"$new" voxelize "$(dirname "$0")/../samples/meshes/glossy_cornell.obj" "$work/glossy.vdb" --res 48 \
  --quiet
"$new" solve "$work/cornell.vdb" "$work/lit.vdb" --directions 100 --iterations 4 --quiet
workloads=(
  "surface: Cornell 160, 300 directions, 8 sweeps, no cache|solve $work/cornell.vdb OUT --directions 300 --iterations 8 --tolerance 0 --visibility-cache 0 --threads 1"
  "surface: glossy-free, 2 threads, cache auto|solve $work/cornell.vdb OUT --directions 300 --iterations 8 --tolerance 0 --threads 2"
  "cloud: cumulus 64, isotropic, 300 directions, 10 sweeps|solve-cloud $work/cumulus.vdb OUT --directions 300 --iterations 10 --tolerance 0 --threads 1"
  "cloud: cumulus 64, g 0.85, order 8, 500 directions, 4 sweeps|solve-cloud $work/cumulus.vdb OUT --g 0.85 --phase-order 8 --directions 500 --iterations 4 --tolerance 0 --threads 1"
  "cloud: slab 32 periodic, ground 0.3, 300 directions, 10 sweeps|solve-cloud $work/slab.vdb OUT --periodic --ground-albedo 0.3 --directions 300 --iterations 10 --tolerance 0 --threads 1"
  "surface: Cornell 160, Anderson, 300 directions, 8 sweeps|solve $work/cornell.vdb OUT --directions 300 --iterations 8 --tolerance 0 --accelerate anderson --threads 1"
  "glossy: glossy Cornell 48, 162 points, 100 directions, 3 sweeps|solve $work/glossy.vdb OUT --directions 100 --iterations 3 --tolerance 0 --threads 1"
  "mesh: voxelize the Cornell box OBJ at 384|voxelize $(dirname "$0")/../samples/meshes/cornell_box.obj OUT --res 384"
  "render: solved Cornell 160, 320x240|render $work/lit.vdb OUT.exr --res 320x240"
)
printf '%-64s %9s %9s %7s %s\n' workload "old s" "new s" ratio bits
for w in "${workloads[@]}"; do
  name=${w%%|*} args=${w#*|}
  best_old=1e9 best_new=1e9
  for r in $(seq "$rounds"); do
    for which in old new; do
      tool=$old; [ $which = new ] && tool=$new
      out="$work/$which.vdb"; rm -f "$out" "$out.exr"
      t0=$(date +%s.%N)
      # shellcheck disable=SC2086
      "$tool" ${args//OUT/$out} --quiet --overwrite
      t=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { print b - a }')
      if [ $which = old ]; then best_old=$(awk -v a="$t" -v b="$best_old" 'BEGIN { print (a < b ? a : b) }')
      else best_new=$(awk -v a="$t" -v b="$best_new" 'BEGIN { print (a < b ? a : b) }'); fi
    done
  done
  if [ -f "$work/new.vdb.exr" ]; then
    same=$(cmp -s "$work/new.vdb.exr" "$work/old.vdb.exr" && echo same || echo DIFFERENT)
  else
  same=$(/usr/bin/python3 - "$work/new.vdb" "$work/old.vdb" <<'PY'
import sys, pyopenvdb as vdb
# Debian's pyopenvdb reads float, vec3s and bool grids only (not the voxelizer's material_id).
NAMES = ("radiosity", "specular_radiosity", "mean_intensity", "ground_irradiance", "normal",
         "albedo", "emission", "specular", "roughness")
def values(path):
    out = {}
    for name in NAMES:
        try:
            g = vdb.read(path, name)
        except Exception:
            continue
        out[name] = [(tuple(v.min), v.value) for v in g.citerOnValues()]
    return out
a, b = values(sys.argv[1]), values(sys.argv[2])
print("same" if a and a == b else "DIFFERENT")
PY
)
  fi
  printf '%-64s %9.3f %9.3f %7.3f %s\n' "$name" "$best_old" "$best_new" \
    "$(awk -v a="$best_new" -v b="$best_old" 'BEGIN { print a / b }')" "$same"
done
