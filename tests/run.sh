#!/usr/bin/env bash
# Runs every test of skein. Installs what the tests need on a fresh machine (Rust
# toolchain, Python 3.11 with pip and apt-get assumed), idempotently:
#   - .venv with the independent peers (tests/peers/requirements.txt)
#   - .venv-ros2 and .venv-ros2-kilted with ROS 2's rclpy on Fast DDS, and skein_msgs built
#     by ROS 2's generators with Debian's cmake (tests/peers/ros2/setup.sh)
#   - Debian's chromium and chromium-driver for the dashboard test
#   - Debian's openssl for the HTTPS test's certificate
#   - cargo-fuzz, for the fuzz smoke run (tests/fuzz.sh: each target 60 s) after the tests
#   - Debian's ffmpeg, the RTSP/H.264 camera of e2e_video (tests/peers/rtsp_server.py)
#   - for the deployment tests (deploy_*): Debian's gcc-aarch64-linux-gnu (the arm64 cross
#     linker), g++-aarch64-linux-gnu (OpenH264's C++) and qemu-user (runs the arm64 image's files), systemd (systemd-analyze),
#     docker-compose when Docker has no Compose v2, and the Rust target
#     aarch64-unknown-linux-gnu (the base images are made by the tests, once per machine)
# The tests run in two lanes side by side (tests/lanes.sh); with arguments (test filters,
# `-p CRATE`) this runs `cargo test --workspace` with them instead, and no fuzzing.
set -euo pipefail
cd "$(dirname "$0")/.."

req=tests/peers/requirements.txt
if [ ! -x .venv/bin/python ] || ! cmp -s "$req" .venv/.skein-requirements; then
  echo "tests/run.sh: preparing .venv from $req" >&2
  python3 -m venv .venv
  .venv/bin/python -m pip install --quiet --disable-pip-version-check -r "$req"
  cp "$req" .venv/.skein-requirements
fi

# The ROS 2 peers (tests/e2e_ros2.rs): built once per machine, again when a message
# package or the wheels change.
tests/peers/ros2/setup.sh

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

# The deployment tests: the arm64 cross-build and its qemu smoke test, the units, compose.
missing=()
command -v aarch64-linux-gnu-gcc >/dev/null 2>&1 || missing+=(gcc-aarch64-linux-gnu)
# The camera plugin's H.264 decoder (OpenH264) is C++: its arm64 build needs the cross g++.
command -v aarch64-linux-gnu-g++ >/dev/null 2>&1 || missing+=(g++-aarch64-linux-gnu)
# The RTSP camera of e2e_video: Debian's ffmpeg encodes H.264 (libx264).
command -v ffmpeg >/dev/null 2>&1 || missing+=(ffmpeg)
command -v qemu-aarch64 >/dev/null 2>&1 || missing+=(qemu-user)
command -v systemd-analyze >/dev/null 2>&1 || missing+=(systemd)
if ! docker compose version >/dev/null 2>&1 && ! command -v docker-compose >/dev/null 2>&1; then
  missing+=(docker-compose)
fi
if [ ${#missing[@]} -gt 0 ]; then
  echo "tests/run.sh: installing ${missing[*]}" >&2
  sudo=""
  [ "$(id -u)" = 0 ] || sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}" >/dev/null
fi
if ! rustup target list --installed | grep -qx aarch64-unknown-linux-gnu; then
  echo "tests/run.sh: adding the Rust target aarch64-unknown-linux-gnu" >&2
  rustup target add aarch64-unknown-linux-gnu
fi

export SKEIN_PYTHON="$PWD/.venv/bin/python"
# The plugin tests build the plugin libraries with this run's package selection, so that
# shared dependencies are not compiled a second time with other features.
export SKEIN_PLUGIN_TEST_SELECTION=workspace
if [ $# -gt 0 ]; then
  # A partial run (the caller's filters): as cargo runs it.
  exec cargo test --workspace --locked "$@"
fi
tests/lanes.sh
tests/fuzz.sh
