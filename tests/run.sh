#!/usr/bin/env bash
# Runs every test of skein. Installs what the tests need on a fresh machine (Rust
# toolchain, Python 3.11 with pip and apt-get assumed), idempotently:
#   - .venv with the independent peers (tests/peers/requirements.txt)
#   - Debian's chromium and chromium-driver for the dashboard test
#   - Debian's openssl for the HTTPS test's certificate
#   - cargo-fuzz, for the fuzz smoke run (tests/fuzz.sh: each target 60 s) after the tests
set -euo pipefail
cd "$(dirname "$0")/.."

req=tests/peers/requirements.txt
if [ ! -x .venv/bin/python ] || ! cmp -s "$req" .venv/.skein-requirements; then
  echo "tests/run.sh: preparing .venv from $req" >&2
  python3 -m venv .venv
  .venv/bin/python -m pip install --quiet --disable-pip-version-check -r "$req"
  cp "$req" .venv/.skein-requirements
fi

have_chromium() {
  command -v chromedriver >/dev/null 2>&1 &&
    { command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1; }
}
if ! have_chromium; then
  echo "tests/run.sh: installing chromium and chromium-driver" >&2
  sudo=""
  [ "$(id -u)" = 0 ] || sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq chromium chromium-driver >/dev/null
fi

# The HTTPS test makes its self-signed certificate with the openssl command-line tool.
if ! command -v openssl >/dev/null 2>&1; then
  echo "tests/run.sh: installing openssl" >&2
  sudo=""
  [ "$(id -u)" = 0 ] || sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq openssl >/dev/null
fi

export SKEIN_PYTHON="$PWD/.venv/bin/python"
# The plugin tests build the plugin libraries with this run's package selection, so that
# shared dependencies are not compiled a second time with other features.
export SKEIN_PLUGIN_TEST_SELECTION=workspace
cargo test --workspace --locked "$@"
# Fuzz smoke run, unless the caller passed test filters (a partial run).
if [ $# -eq 0 ]; then
  tests/fuzz.sh
fi
