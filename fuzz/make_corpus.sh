#!/bin/bash
# Seed corpus for fuzz/fuzz_load.cc, generated rather than committed: small files of every kind
# the tool reads (each canonical scene, explicit surfaces, solved scenes and clouds, a level set).
#   VDBRAD=build/vdbrad fuzz/make_corpus.sh corpus/
set -euo pipefail
out=${1:?usage: make_corpus.sh OUTDIR}
vdbrad=${VDBRAD:-vdbrad}
mkdir -p "$out"
for scene in furnace-box furnace-sphere disk plates cornell slab cumulus; do
    for res in 4 8; do
        "$vdbrad" make "$scene" "$out/$scene-$res.vdb" --res "$res" --quiet
    done
done
"$vdbrad" surface "$out/cornell-8.vdb" "$out/cornell-surface.vdb" --quiet
"$vdbrad" solve "$out/furnace-box-4.vdb" "$out/furnace-solved.vdb" --quiet --directions 3 \
    --iterations 1
"$vdbrad" solve "$out/cornell-8.vdb" "$out/cornell-solved.vdb" --quiet --directions 3 \
    --iterations 1
"$vdbrad" solve-cloud "$out/slab-4.vdb" "$out/slab-solved.vdb" --quiet --directions 3 \
    --iterations 1
if command -v vdb_tool > /dev/null; then
    vdb_tool -quiet -sphere r=1 dim=8 -o "$out/sphere-ls.vdb"
fi
ls "$out" | wc -l
