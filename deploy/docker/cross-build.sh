#!/usr/bin/env bash
# Cross-compiles skein and its payload plugins for the arm64 companions (Raspberry Pi 4,
# Jetson Orin NX): target aarch64-unknown-linux-gnu, linked by Debian's cross gcc
# (.cargo/config.toml), on this machine.
#
#   deploy/docker/cross-build.sh [--profile release|dev|arm64-test] [--target-dir DIR]
#
# Needs `rustup target add aarch64-unknown-linux-gnu`, Debian's gcc-aarch64-linux-gnu and,
# for the camera plugin's OpenH264 (C++), g++-aarch64-linux-gnu (tests/run.sh installs
# them); fetches Debian's arm64 OpenSSL 3 (libssl-dev, libssl3) once, for DDS Security. Builds only what the image holds (skein and the gimbal,
# camera, detector, radio and example plugins, one cargo invocation so that they share
# one build of their dependencies) and prints the directory that has them, for
# `build-image.sh --arch arm64 DIR`. The binary needs glibc 2.35 or newer (Raspberry Pi
# OS bookworm, Ubuntu 22.04 / JetPack 6); the image brings its own.
set -euo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)
triple=aarch64-unknown-linux-gnu
profile=release
target_dir=$repo/target
while [ $# -gt 0 ]; do
  case "$1" in
    --profile) profile=$2; shift 2 ;;
    --target-dir) target_dir=$2; shift 2 ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    *) echo "cross-build.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
if command -v rustup >/dev/null 2>&1 && ! rustup target list --installed | grep -qx "$triple"; then
  echo "cross-build.sh: no Rust standard library for $triple: rustup target add $triple" >&2
  exit 1
fi
if ! command -v aarch64-linux-gnu-gcc >/dev/null 2>&1; then
  echo "cross-build.sh: no cross linker: apt-get install gcc-aarch64-linux-gnu" >&2
  exit 1
fi
if ! command -v aarch64-linux-gnu-g++ >/dev/null 2>&1; then
  echo "cross-build.sh: no cross C++ compiler (OpenH264): apt-get install g++-aarch64-linux-gnu" >&2
  exit 1
fi
# DDS Security links OpenSSL 3 (openssl-sys): the arm64 headers and libraries of
# Debian's libssl-dev and libssl3, unpacked once under ~/.cache/skein (the image's base
# carries the same libssl3 at run time, make-base.sh).
ssl_root=${XDG_CACHE_HOME:-$HOME/.cache}/skein/openssl-arm64
ssl_include=$ssl_root/include
if [ ! -e "$ssl_include/openssl/opensslconf.h" ]; then
  # shellcheck source=deploy/docker/apt-foreign.sh
  . "$repo/deploy/docker/apt-foreign.sh"
  apt_foreign_init arm64
  rm -rf "$ssl_root"
  apt_foreign_unpack "$ssl_root/debs" libssl-dev:arm64 libssl3:arm64
  # One include directory: the generic headers and the architecture's configuration.
  mkdir -p "$ssl_include/openssl"
  cp -r "$ssl_root/debs/usr/include/openssl/." "$ssl_root/debs/usr/include/aarch64-linux-gnu/openssl/." \
    "$ssl_include/openssl/"
fi
export AARCH64_UNKNOWN_LINUX_GNU_OPENSSL_INCLUDE_DIR=$ssl_include
export AARCH64_UNKNOWN_LINUX_GNU_OPENSSL_LIB_DIR=$ssl_root/debs/usr/lib/aarch64-linux-gnu
# A program cargo runs (a test calling this script) has its own package's
# CARGO_MANIFEST_DIR, CARGO_PKG_* ... in its environment; build scripts that track them
# (ring's) would see another build than from a shell, and rebuild ring and everything on
# it. This build is the repository's, whoever calls it.
for v in $(compgen -e); do
  case "$v" in
    CARGO_MANIFEST_*|CARGO_PKG_*|CARGO_CRATE_NAME|CARGO_BIN_*|CARGO_PRIMARY_PACKAGE|\
      CARGO_TARGET_TMPDIR|CARGO_RUSTC_CURRENT_DIR|OUT_DIR) unset "$v" ;;
  esac
done
cd "$repo"
cargo build --locked --target "$triple" --profile "$profile" --target-dir "$target_dir" \
  -p skein -p skein-plugin-gimbal -p skein-plugin-camera -p skein-plugin-detector \
  -p skein-plugin-radio -p skein-plugin-example
case "$profile" in
  dev|test) out=debug ;;
  *) out=$profile ;;
esac
echo "$target_dir/$triple/$out"
