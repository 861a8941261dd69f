#!/usr/bin/env bash
# Runs every test of skein. Installs what the tests need on a fresh machine (Rust
# toolchain, Python 3.11 with pip and apt-get assumed), idempotently:
#   - .venv with the independent peers (tests/peers/requirements.txt)
#   - .venv-ros2 and .venv-ros2-kilted with ROS 2's rclpy on Fast DDS, and skein_msgs built
#     by ROS 2's generators with Debian's cmake (tests/peers/ros2/setup.sh)
#   - Debian's chromium and chromium-driver for the dashboard test
#   - Debian's openssl for the HTTPS test's certificate
#   - cargo-fuzz, for the fuzz smoke run (tests/fuzz.sh: each target 45 s) after the tests
#   - Debian's ffmpeg, the RTSP/H.264 camera of e2e_video (tests/peers/rtsp_server.py)
#   - Debian's rtklib, whose str2str serves the NTRIP caster of e2e_rtk
#   - Debian's gpsd and gpsd-clients (gpsfake): the ground station's GNSS receiver of
#     e2e_swarm's Remote ID test
#   - for the deployment tests (deploy_*): Debian's gcc-aarch64-linux-gnu (the arm64 cross
#     linker), g++-aarch64-linux-gnu (OpenH264's C++) and qemu-user (runs the arm64 image's files), systemd (systemd-analyze),
#     docker-compose when Docker has no Compose v2, and the Rust target
#     aarch64-unknown-linux-gnu (the base images are made by the tests, once per machine)
# The installs run beside the test build (on a fresh machine they are minutes of
# downloads and unpacking, which leave the cores to the compiler); the tests wait for
# both. The tests run in two lanes side by side (tests/lanes.sh); with arguments (test
# filters, `-p CRATE`) this runs `cargo test --workspace` with them instead, after the
# installs, and no fuzzing.
set -euo pipefail
cd "$(dirname "$0")/.."

# `apt_install PACKAGE...`: Debian's packages, as root or through sudo.
apt_install() {
  local sudo=""
  [ "$(id -u)" = 0 ] || sudo="sudo"
  echo "tests/run.sh: installing $*" >&2
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "$@" >/dev/null
}

# What the build itself needs: C and C++ compilers (the plugins' and OpenH264's build
# scripts), OpenSSL's headers, and cmake and make (tests/peers/ros2/setup.sh, which would otherwise install
# them itself, beside this script's own apt-get).
build_needs=()
command -v cc >/dev/null 2>&1 || build_needs+=(gcc)
command -v c++ >/dev/null 2>&1 || build_needs+=(g++)
command -v cmake >/dev/null 2>&1 || build_needs+=(cmake)
command -v make >/dev/null 2>&1 || build_needs+=(make)
# DDS Security (RustDDS's `security`) links the system's OpenSSL 3: its headers, and
# pkg-config to find them.
[ -e /usr/include/openssl/ssl.h ] || build_needs+=(libssl-dev)
command -v pkg-config >/dev/null 2>&1 || build_needs+=(pkg-config)
[ ${#build_needs[@]} -eq 0 ] || apt_install "${build_needs[@]}"

# Everything else the tests need (see the top of this file).
prepare() {
  local req=tests/peers/requirements.txt
  if [ ! -x .venv/bin/python ] || ! cmp -s "$req" .venv/.skein-requirements; then
    echo "tests/run.sh: preparing .venv from $req" >&2
    python3 -m venv .venv
    .venv/bin/python -m pip install --quiet --disable-pip-version-check -r "$req"
    cp "$req" .venv/.skein-requirements
  fi
  # The ROS 2 peers (tests/e2e_ros2.rs): built once per machine, again when a message
  # package or the wheels change.
  tests/peers/ros2/setup.sh
  local missing=()
  # The dashboard tests.
  command -v chromedriver >/dev/null 2>&1 || missing+=(chromium-driver)
  command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 ||
    missing+=(chromium)
  # The HTTPS test makes its self-signed certificate with the openssl command-line tool.
  command -v openssl >/dev/null 2>&1 || missing+=(openssl)
  # The RTSP camera of e2e_video: Debian's ffmpeg encodes H.264 (libx264).
  command -v ffmpeg >/dev/null 2>&1 || missing+=(ffmpeg)
  # The NTRIP caster of e2e_rtk: RTKLIB's str2str.
  command -v str2str >/dev/null 2>&1 || missing+=(rtklib)
  # The ground station's GNSS receiver of e2e_swarm's Remote ID test: Debian's gpsd fed
  # by its own gpsfake (in gpsd-clients on Debian 12).
  [ -x /usr/sbin/gpsd ] || command -v gpsd >/dev/null 2>&1 || missing+=(gpsd)
  command -v gpsfake >/dev/null 2>&1 || missing+=(gpsd-clients)
  # The deployment tests: the arm64 cross-build and its qemu smoke test, the units,
  # compose. The camera plugin's H.264 decoder (OpenH264) is C++: its arm64 build needs
  # the cross g++.
  command -v aarch64-linux-gnu-gcc >/dev/null 2>&1 || missing+=(gcc-aarch64-linux-gnu)
  command -v aarch64-linux-gnu-g++ >/dev/null 2>&1 || missing+=(g++-aarch64-linux-gnu)
  command -v qemu-aarch64 >/dev/null 2>&1 || missing+=(qemu-user)
  command -v systemd-analyze >/dev/null 2>&1 || missing+=(systemd)
  if ! docker compose version >/dev/null 2>&1 && ! command -v docker-compose >/dev/null 2>&1; then
    missing+=(docker-compose)
  fi
  [ ${#missing[@]} -eq 0 ] || apt_install "${missing[@]}"
  if ! rustup target list --installed | grep -qx aarch64-unknown-linux-gnu; then
    echo "tests/run.sh: adding the Rust target aarch64-unknown-linux-gnu" >&2
    rustup target add aarch64-unknown-linux-gnu
  fi
}

export SKEIN_PYTHON="$PWD/.venv/bin/python"
# The plugin tests build the plugin libraries with this run's package selection, so that
# shared dependencies are not compiled a second time with other features.
export SKEIN_PLUGIN_TEST_SELECTION=workspace
# A failing test's panic is its message and its file and line, without the 40 lines of a
# backtrace that pushed the message out of CI's excerpt of the log (once, all of it);
# SKEIN_TEST_BACKTRACE=1 gives them back.
export RUST_BACKTRACE="${SKEIN_TEST_BACKTRACE:-0}"
if [ $# -gt 0 ]; then
  # A partial run (the caller's filters): as cargo runs it, once everything is in place.
  prepare
  exec cargo test --workspace --locked "$@"
fi
mkdir -p target
prepare_log=target/prepare.log
started=$(date +%s)
{
  prepare
  echo "tests/run.sh: installs done in $(($(date +%s) - started)) s"
} >"$prepare_log" 2>&1 &
pid_prepare=$!
build_rc=0
cargo test --workspace --locked --no-run || build_rc=$?
echo "tests/run.sh: build done in $(($(date +%s) - started)) s" >&2
prepare_rc=0
wait "$pid_prepare" || prepare_rc=$?
cat "$prepare_log" >&2
if [ "$prepare_rc" -ne 0 ]; then
  echo "tests/run.sh: installing what the tests need failed (exit $prepare_rc)" >&2
  exit "$prepare_rc"
fi
echo "tests/run.sh: build and installs done in $(($(date +%s) - started)) s" >&2
[ "$build_rc" -eq 0 ] || exit "$build_rc"
tests/lanes.sh
tests/fuzz.sh
