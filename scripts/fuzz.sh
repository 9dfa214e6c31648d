#!/usr/bin/env bash
# Builds every fuzz/fuzz_*.cc as a libFuzzer program with clang (build-hardening/, shared with
# scripts/sanitize.sh; library instrumented with ASan + UBSan) and runs each for FUZZ_SECONDS
# (default 30) from the seed corpus the target writes itself (fuzz/Seeds.h). Fails on any
# crash, sanitizer report, leak, uncaught exception, hang (> 120 s on one input, see below) or
# memory blow-up (> 2 GiB); the input is kept in
# build-hardening/artifacts/ (replay: build-hardening/fuzz/NAME build-hardening/artifacts/FILE).
# FUZZ_TARGETS: names to run (default: all); further arguments go to libFuzzer, e.g. -runs=N.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${FUZZ_SECONDS:-30}
targets=${FUZZ_TARGETS:-$(for f in fuzz/fuzz_*.cc; do basename "$f" .cc; done)}

# The configuration scripts/sanitize.sh made, test suites and all (nothing rebuilt after it).
# shellcheck source=scripts/hardening-build.sh
source scripts/hardening-build.sh
# shellcheck disable=SC2086 # one target name per word
cmake --build build-hardening -j"$(nproc)" --target $targets

export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
export LSAN_OPTIONS="suppressions=$PWD/scripts/lsan.supp:print_suppressions=0"
mkdir -p build-hardening/artifacts build-hardening/logs
status=0
# -timeout=120: above what the file guard (CrashGuard.cc runGuarded) may take on its own: a child
# that hung on a lock copied by fork() is killed after 3 x its CPU budget + 15 s and retried once,
# so a seed of 125 KB can take ~40 s there before it parses (a 10 s limit failed a CI run so).
for name in $targets; do
  corpus=build-hardening/corpus/$name
  log=build-hardening/logs/$name.log
  mkdir -p "$corpus"
  echo "fuzz: $name for ${seconds} s (log: $log)"
  if VDBRAD_FUZZ_SEEDS=$corpus "build-hardening/fuzz/$name" "$corpus" -max_total_time="$seconds" \
      -timeout=120 -rss_limit_mb=2048 -artifact_prefix="build-hardening/artifacts/$name-" \
      -print_final_stats=1 "$@" >"$log" 2>&1; then
    grep -E "^(Done|stat::(number_of_executed_units|average_exec_per_sec|new_units_added))" \
      "$log" | sed "s/^/  /"
  else
    echo "fuzz: $name FAILED; the end of $log:" >&2
    tail -n 60 "$log" >&2
    status=1
  fi
done
exit $status
