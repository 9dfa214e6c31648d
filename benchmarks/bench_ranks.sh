#!/usr/bin/env bash
# Strong scaling of a distributed solve on this machine (issue 26, thesis §6.2.1.2): the same
# solve in one process and under mpirun, same script, same input; wall seconds, ratios against
# one process with as many threads, the bytes rank 0 exchanged and the seconds it spent in the
# exchanges (waiting for the slower rank included), and whether the bits match.
#
#   bash benchmarks/bench_ranks.sh                    (Cornell box res 128, 1000 directions)
#   RES=64 DIRS=300 CACHE=0 bash benchmarks/bench_ranks.sh   (CACHE=0: sweep every iteration)
set -euo pipefail
cd "$(dirname "$0")/.."
V=${VDBRAD:-$PWD/build/vdbrad}
res=${RES:-128}
dirs=${DIRS:-1000}
cache=${CACHE:-auto}
cores=$(nproc)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
"$V" make cornell c.vdb --res "$res" --quiet
opts="--directions $dirs --tolerance 1e-4 --visibility-cache $cache"
wall() { local t0=$(date +%s.%N); "$@"; echo "$(date +%s.%N) - $t0" | bc; }
mpirun=(mpirun --oversubscribe --allow-run-as-root)
echo "# Cornell box res $res, $dirs directions, tolerance 1e-4, visibility cache $cache; $cores cores"
printf '%-34s %9s %7s  %s\n' run "wall s" ratio "exchanges (rank 0)"
base=$(wall "$V" solve c.vdb s.vdb $opts --quiet --threads "$cores")
printf '%-34s %9.2f %7.2f\n' "1 process x $cores threads" "$base" 1
one=$(wall "$V" solve c.vdb s1.vdb $opts --quiet --threads 1)
printf '%-34s %9.2f %7.2f\n' "1 process x 1 thread" "$one" "$(echo "$one / $base" | bc -l)"
for k in 2 3 4; do
  t=$((cores / k)); [ "$t" -ge 1 ] || t=1
  secs=$(wall "${mpirun[@]}" -np $k "$V" solve c.vdb r$k.vdb $opts --threads $t 2> r$k.err)
  same=$("$V" compare s.vdb r$k.vdb | grep -q "max_rel 0$" && echo "same bits" || echo DIFFERENT)
  printf '%-34s %9.2f %7.2f  %s; %s\n' "mpirun -np $k x $t threads" "$secs" \
    "$(echo "$secs / $base" | bc -l)" "$(grep -o 'exchanged.*' r$k.err)" "$same"
done
