#!/usr/bin/env bash
# Builds skein's image from binaries cargo built outside it (nothing is compiled in the
# image):
#
#   deploy/docker/build-image.sh [--arch amd64|arm64] [--base IMAGE] [--tag TAG] [BIN_DIR]
#
#   BIN_DIR  where `skein` and the plugin libraries are: default target/release (amd64)
#            or target/aarch64-unknown-linux-gnu/release (arm64; cross-build.sh builds it)
#   --base   the base image: default skein-base:bookworm-ARCH, made by make-base.sh from
#            this machine's own files when missing (no registry needed); with a registry,
#            debian:bookworm-slim (or an L4T base for a Jetson, see docs)
#   --tag    default skein:VERSION-ARCH (VERSION from Cargo.toml), as the seed tags them
#
# The binary and the payload plugins (gimbal, camera, detector, radio, example) are copied
# into a staging context, stripped (debug info and symbols are most of their size), and
# put on the base by deploy/docker/Dockerfile. Prints the tag and the image's size.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)

arch=$(dpkg --print-architecture)
base=""
tag=""
bin_dir=""
while [ $# -gt 0 ]; do
  case "$1" in
    --arch) arch=$2; shift 2 ;;
    --base) base=$2; shift 2 ;;
    --tag) tag=$2; shift 2 ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    -*) echo "build-image.sh: unknown option $1" >&2; exit 2 ;;
    *) bin_dir=$1; shift ;;
  esac
done
case "$arch" in
  amd64) machine="X86-64"; triple=x86_64-unknown-linux-gnu ;;
  arm64) machine="AArch64"; triple=aarch64-unknown-linux-gnu ;;
  *) echo "build-image.sh: --arch $arch: amd64 or arm64" >&2; exit 2 ;;
esac
host_arch=$(dpkg --print-architecture)
if [ "$arch" = "$host_arch" ]; then
  strip=strip
  bin_dir=${bin_dir:-$repo/target/release}
else
  strip=${triple%%-unknown-*}-linux-gnu-strip
  bin_dir=${bin_dir:-$repo/target/$triple/release}
fi
version=$(sed -n '/^\[workspace.package\]/,/^\[/s/^version = "\(.*\)"/\1/p' "$repo/Cargo.toml")
tag=${tag:-skein:$version-$arch}
if [ -z "$base" ]; then
  base=$("$here/make-base.sh" --arch "$arch")
fi

plugins=(gimbal camera detector radio example)
missing=()
[ -f "$bin_dir/skein" ] || missing+=("skein")
for p in "${plugins[@]}"; do
  [ -f "$bin_dir/libskein_plugin_$p.so" ] || missing+=("libskein_plugin_$p.so")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "build-image.sh: not in $bin_dir: ${missing[*]} (build them first: cargo build --release," \
    "or deploy/docker/cross-build.sh for arm64)" >&2
  exit 1
fi
if ! readelf -h "$bin_dir/skein" | grep -q "Machine:.*$machine"; then
  echo "build-image.sh: $bin_dir/skein is not an $arch binary ($(readelf -h "$bin_dir/skein" |
    sed -n 's/ *Machine: *//p'))" >&2
  exit 1
fi

context=$(mktemp -d)
trap 'rm -rf "$context"' EXIT
mkdir -p "$context/plugins" "$context/home"
"$strip" -o "$context/skein" "$bin_dir/skein"
for p in "${plugins[@]}"; do
  "$strip" -o "$context/plugins/libskein_plugin_$p.so" "$bin_dir/libskein_plugin_$p.so"
done
cp "$here/Dockerfile" "$context/Dockerfile"
docker build -q --platform "linux/$arch" --build-arg "BASE=$base" \
  --build-arg "VERSION=$version" -t "$tag" "$context" >/dev/null
size=$(docker image inspect -f '{{.Size}}' "$tag")
echo "$tag $size"
