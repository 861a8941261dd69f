#!/usr/bin/env bash
# Fuzz smoke run: every cargo-fuzz target of fuzz/ for SKEIN_FUZZ_SECONDS (default 45) s
# of CPU, the targets side by side (all at once: five on two cores run 113 s each),
# starting from its committed corpus (fuzz/corpus/<target>/, copied to a scratch directory
# so the run leaves the tree clean). A crash fails the run and leaves the input in
# fuzz/artifacts/<target>/. Installs cargo-fuzz if missing, idempotently.
#   tests/fuzz.sh                      # all targets, 45 s each
#   SKEIN_FUZZ_SECONDS=3600 tests/fuzz.sh mavlink_ingress   # one long run
#   tests/fuzz.sh --build-only         # install and build, run nothing (tests/lanes.sh
#                                      # does this beside the tests, at idle priority)
set -euo pipefail
cd "$(dirname "$0")/.."
build_only=0
if [ "${1:-}" = "--build-only" ]; then
  build_only=1
  shift
fi

if ! cargo fuzz --version >/dev/null 2>&1; then
  echo "tests/fuzz.sh: installing cargo-fuzz" >&2
  # Unoptimised (--debug): it only runs cargo, and its optimised build was about 2.5
  # minutes of CPU in every CI run on a fresh machine.
  cargo install cargo-fuzz --locked --version 0.13.2 --debug
fi
# cargo fuzz instruments with -Z flags; this machine has the stable toolchain only.
export RUSTC_BOOTSTRAP=1
seconds="${SKEIN_FUZZ_SECONDS:-45}"
cd fuzz
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  mapfile -t targets < <(cargo fuzz list)
fi
# Build every target once, then run them side by side, as many at a time as there are
# cores (libFuzzer runs one process per target, each on one core).
build_log=$(mktemp)
for t in "${targets[@]}"; do
  cargo fuzz build --sanitizer none "$t" >"$build_log" 2>&1 || {
    tail -60 "$build_log" >&2
    echo "tests/fuzz.sh: building $t failed" >&2
    exit 1
  }
done
rm -f "$build_log"
[ "$build_only" = 1 ] && exit 0
# Every target at once. With more targets than cores, each runs for seconds × targets /
# cores of wall time: it gets about `seconds` of CPU, as with one target per core, and no
# core idles while a last round's lone target runs (five targets on two cores in rounds
# were three rounds of 45 s, the last on one core).
cores=$(nproc)
wall=$seconds
if [ ${#targets[@]} -gt "$cores" ]; then
  wall=$(((seconds * ${#targets[@]} + cores - 1) / cores))
fi
declare -A pids scratch_of
failed=""
finish() { # target: waits for it, reports its stats, keeps its scratch on failure
  local t=$1 status=0
  wait "${pids[$t]}" || status=$?
  local s=${scratch_of[$t]}
  echo "tests/fuzz.sh: $t:" >&2
  grep -E 'stat::number_of_executed_units|stat::peak_rss_mb|^Done' "$s.log" >&2 || true
  if [ "$status" -ne 0 ]; then
    tail -60 "$s.log" >&2
    echo "tests/fuzz.sh: $t failed (exit $status); the input is in fuzz/artifacts/$t/" >&2
    failed="$failed $t"
  fi
  rm -rf "$s" "$s.log"
}
for t in "${targets[@]}"; do
  scratch=$(mktemp -d)
  cp -r "corpus/$t/." "$scratch/"
  scratch_of[$t]=$scratch
  echo "tests/fuzz.sh: $t for ${wall} s beside the others (${seconds} s of CPU)" >&2
  # Safe Rust: no sanitizer (faster); debug assertions stay on (overflow checks).
  cargo fuzz run --sanitizer none "$t" "$scratch" -- \
    -max_total_time="$wall" -print_final_stats=1 >"$scratch.log" 2>&1 &
  pids[$t]=$!
done
for t in "${targets[@]}"; do
  finish "$t"
done
if [ -n "$failed" ]; then
  echo "tests/fuzz.sh: failed:$failed" >&2
  exit 1
fi
