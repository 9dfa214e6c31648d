#!/usr/bin/env bash
# Data distribution (issue 26 part 3, thesis §6.2.2.3): the same solve in one process and under
# mpirun with the scene cut into slabs along x (--distribute slabs) or with every rank holding it
# (--distribute directions), same script, same input. Per run: wall seconds, ratio against one
# process with one thread (a slab rank runs one thread), the last iteration's seconds, each rank's
# peak resident memory (the largest and the smallest: reading the input, which every rank does
# whole), the bytes rank 0 sent and received and the seconds it spent in exchanges (waiting for
# its neighbours' fronts included), the ranks' resident memory while solving (slabs), and whether
# the bits match the serial tool's.
#
#   bash benchmarks/bench_slabs.sh                        (Cornell box res 128, 300 directions)
#   RES=256 DIRS=300 ITERS=4 RANKS="2 3 4" bash benchmarks/bench_slabs.sh
set -euo pipefail
cd "$(dirname "$0")/.."
V=${VDBRAD:-$PWD/build/vdbrad}
res=${RES:-128}
dirs=${DIRS:-300}
iters=${ITERS:-4}
ranks=${RANKS:-2 3 4}
cores=$(nproc)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
"$V" make cornell c.vdb --res "$res" --quiet
voxels=$("$V" info c.vdb | grep -o '[0-9,]* surface voxels' | head -1 || true)
opts="--directions $dirs --iterations $iters --tolerance 0 --visibility-cache 0"
mpirun=(mpirun --oversubscribe --allow-run-as-root)
T=/usr/bin/time
echo "# Cornell box res $res ($voxels), $dirs directions, $iters iterations, no cache; $cores cores"
printf '%-40s %8s %7s %7s %21s  %s\n' run "wall s" ratio "last it" "peak RSS max/min MB" \
  "rank 0's exchanges; resident memory; bits"
run() {   # label, output, command...
  local label=$1 out=$2; shift 2
  local t0 t1
  t0=$(date +%s.%N)
  "$@" 2> "$out.err" || { cat "$out.err" >&2; exit 1; }
  t1=$(date +%s.%N)
  local secs rss
  secs=$(echo "$t1 - $t0" | bc)
  rss=$(grep -o '^rss [0-9]*' "$out.err" | awk '{print $2}' | sort -n)
  local hi lo
  hi=$(echo "$rss" | tail -1); lo=$(echo "$rss" | head -1)
  local same=""
  [ "$out" != base.vdb ] && same=$("$V" compare "$out" base.vdb | grep -q "max_rel 0$" \
    && echo "same bits" || echo DIFFERENT)
  [ -z "${base:-}" ] && base=$secs
  local it
  it=$(grep -o 'iteration [0-9]*: residual [^ ]* in [0-9.]* s' "$out.err" | tail -1 \
    | awk '{print $NF == "s" ? $(NF-1) : ""}')
  printf '%-40s %8.2f %7.2f %7s %10.0f / %8.0f  %s %s %s\n' "$label" "$secs" \
    "$(echo "$secs / $base" | bc -l)" "$it" "$(echo "$hi / 1024" | bc -l)" \
    "$(echo "$lo / 1024" | bc -l)" "$(grep -o 'exchanged.*' "$out.err" || true)" \
    "$(grep -o 'resident while solving.*' "$out.err" || true)" "$same"
}
base=""
run "1 process x 1 thread" base.vdb $T -f "rss %M" "$V" solve c.vdb base.vdb $opts --threads 1
run "1 process x $cores threads" s.vdb $T -f "rss %M" "$V" solve c.vdb s.vdb $opts
for k in $ranks; do
  t=$((cores / k)); [ "$t" -ge 1 ] || t=1
  run "mpirun -np $k directions x $t threads" d$k.vdb "${mpirun[@]}" -np $k \
    $T -f "rss %M" "$V" solve c.vdb d$k.vdb $opts --threads $t
  run "mpirun -np $k slabs" s$k.vdb "${mpirun[@]}" -np $k \
    $T -f "rss %M" "$V" solve c.vdb s$k.vdb $opts --distribute slabs
done
