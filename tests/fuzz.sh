#!/usr/bin/env bash
# Fuzz smoke run: every cargo-fuzz target of fuzz/ for SKEIN_FUZZ_SECONDS (default 60) s,
# starting from its committed corpus (fuzz/corpus/<target>/, copied to a scratch directory
# so the run leaves the tree clean). A crash fails the run and leaves the input in
# fuzz/artifacts/<target>/. Installs cargo-fuzz if missing, idempotently.
#   tests/fuzz.sh                      # all targets, 60 s each
#   SKEIN_FUZZ_SECONDS=3600 tests/fuzz.sh mavlink_ingress   # one long run
set -euo pipefail
cd "$(dirname "$0")/.."

if ! cargo fuzz --version >/dev/null 2>&1; then
  echo "tests/fuzz.sh: installing cargo-fuzz" >&2
  cargo install cargo-fuzz --locked --version 0.13.2
fi
# cargo fuzz instruments with -Z flags; this machine has the stable toolchain only.
export RUSTC_BOOTSTRAP=1
seconds="${SKEIN_FUZZ_SECONDS:-60}"
cd fuzz
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  mapfile -t targets < <(cargo fuzz list)
fi
for t in "${targets[@]}"; do
  scratch=$(mktemp -d)
  cp -r "corpus/$t/." "$scratch/"
  echo "tests/fuzz.sh: $t for ${seconds} s" >&2
  status=0
  # Safe Rust: no sanitizer (faster); debug assertions stay on (overflow checks).
  cargo fuzz run --sanitizer none "$t" "$scratch" -- \
    -max_total_time="$seconds" -print_final_stats=1 >"$scratch.log" 2>&1 || status=$?
  grep -E 'stat::number_of_executed_units|stat::peak_rss_mb|^Done' "$scratch.log" >&2 || true
  if [ "$status" -ne 0 ]; then
    tail -60 "$scratch.log" >&2
    echo "tests/fuzz.sh: $t failed (exit $status); the input is in fuzz/artifacts/$t/" >&2
    rm -rf "$scratch" "$scratch.log"
    exit "$status"
  fi
  rm -rf "$scratch" "$scratch.log"
done
