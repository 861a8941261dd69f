#!/usr/bin/env bash
# Makes the base image skein's image is built on, on a machine that has no registry (or
# wants no pull): the C runtime the `skein` binary and its plugins link (glibc's loader,
# libc, libm, the libdl/libpthread/librt stubs, libgcc_s, libstdc++ for the camera
# plugin's H.264 decoder, OpenH264, which is C++, and OpenSSL 3's libssl and libcrypto for
# DDS Security), /etc/passwd and /etc/group
# with the `skein` user (uid 10001) and `dialout` (gid 20, the serial ports), and /tmp.
# Nothing else: no shell, no package manager (skein needs none; the health check is
# `skein health`).
#
#   deploy/docker/make-base.sh [--arch amd64|arm64] [--tag TAG] [--force]
#
# Where the files come from:
#   - the machine's own architecture: the machine's own installed packages (libc6,
#     libgcc-s1, libstdc++6, libssl3), so the base holds the C library the binaries were linked against here;
#   - another architecture (arm64 on an amd64 machine): the same four Debian packages of
#     that architecture, downloaded with apt-get (apt-foreign.sh).
#
# The image is tagged `skein-base:bookworm-ARCH` (or --tag) and labelled with the libc6
# version and the list of libraries it holds; an image with that tag and labels is reused (this script then takes a second),
# unless --force. Prints the tag. With a registry, `--base debian:bookworm-slim` in
# build-image.sh needs none of this.
set -euo pipefail

arch=$(dpkg --print-architecture)
tag=""
force=0
while [ $# -gt 0 ]; do
  case "$1" in
    --arch) arch=$2; shift 2 ;;
    --tag) tag=$2; shift 2 ;;
    --force) force=1; shift ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    *) echo "make-base.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
case "$arch" in
  amd64) triplet=x86_64-linux-gnu; loader=ld-linux-x86-64.so.2; loader_dir=lib64 ;;
  arm64) triplet=aarch64-linux-gnu; loader=ld-linux-aarch64.so.1; loader_dir=lib ;;
  *) echo "make-base.sh: --arch $arch: amd64 or arm64" >&2; exit 2 ;;
esac
tag=${tag:-skein-base:bookworm-$arch}
host_arch=$(dpkg --print-architecture)

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
root=$work/root
mkdir -p "$root"

# The libc6 version the base holds: the installed one, or the mirror's candidate.
if [ "$arch" = "$host_arch" ]; then
  libc_version=$(dpkg-query -W -f '${Version}' libc6)
else
  # shellcheck source=deploy/docker/apt-foreign.sh
  . "$(dirname "$0")/apt-foreign.sh"
  apt_foreign_init "$arch"
  libc_version=$(apt-cache "${apt_opts[@]}" show --no-all-versions "libc6:$arch" |
    sed -n 's/^Version: //p' | head -n1)
fi
[ -n "$libc_version" ] || { echo "make-base.sh: no libc6 for $arch" >&2; exit 1; }

libs=("$loader" libc.so.6 libm.so.6 libdl.so.2 libpthread.so.0 librt.so.1 libgcc_s.so.1 libstdc++.so.6
  libssl.so.3 libcrypto.so.3)
if [ "$force" = 0 ] &&
  [ "$(docker image inspect -f '{{index .Config.Labels "org.skein.libc6"}} {{index .Config.Labels "org.skein.libs"}}' "$tag" 2>/dev/null)" = "$libc_version ${libs[*]}" ]; then
  echo "$tag"
  exit 0
fi

# Debian's merged /usr: /lib and /lib64 are links into /usr.
mkdir -p "$root/usr/lib/$triplet" "$root/etc" "$root/tmp"
ln -s usr/lib "$root/lib"
if [ "$loader_dir" = lib64 ]; then
  mkdir -p "$root/usr/lib64"
  ln -s usr/lib64 "$root/lib64"
  ln -s "../lib/$triplet/$loader" "$root/usr/lib64/$loader"
else
  ln -s "$triplet/$loader" "$root/usr/lib/$loader"
fi
chmod 1777 "$root/tmp"

if [ "$arch" = "$host_arch" ]; then
  from=""
else
  apt_foreign_unpack "$work/unpacked" "libc6:$arch" "libgcc-s1:$arch" "libstdc++6:$arch" \
    "libssl3:$arch"
  from=$work/unpacked
fi
for lib in "${libs[@]}"; do
  # Packages not yet merged put a library under /lib or /usr/lib; cp -L: the file itself,
  # wherever a link of the package points.
  src=""
  for dir in "$from/usr/lib/$triplet" "$from/lib/$triplet"; do
    [ -e "$dir/$lib" ] && { src=$dir/$lib; break; }
  done
  [ -n "$src" ] || { echo "make-base.sh: no $lib in libc6/libgcc-s1/libstdc++6/libssl3 ($arch)" >&2; exit 1; }
  cp -L "$src" "$root/usr/lib/$triplet/$lib"
done

cat >"$root/etc/passwd" <<'EOF'
root:x:0:0:root:/root:/usr/sbin/nologin
skein:x:10001:10001:skein:/var/lib/skein:/usr/sbin/nologin
nobody:x:65534:65534:nobody:/nonexistent:/usr/sbin/nologin
EOF
cat >"$root/etc/group" <<'EOF'
root:x:0:
dialout:x:20:skein
skein:x:10001:
nogroup:x:65534:
EOF
# glibc reads these for names and hosts (the resolver itself is in libc since 2.34).
printf 'passwd: files\ngroup: files\nhosts: files dns\n' >"$root/etc/nsswitch.conf"

# An image archive as `docker save` writes it (one layer, a config naming the
# architecture), for `docker load`: `docker import` would label it with this machine's
# architecture whatever the files are.
image=$work/image
mkdir -p "$image/layer"
tar -C "$root" --numeric-owner --owner=0 --group=0 --sort=name -cf "$image/layer/layer.tar" .
diff_id=$(sha256sum "$image/layer/layer.tar" | cut -d' ' -f1)
created=$(date -u +%Y-%m-%dT%H:%M:%SZ)
cat >"$image/config.json" <<EOF
{"architecture": "$arch", "os": "linux", "created": "$created",
 "config": {"Env": ["PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin"],
            "Labels": {"org.skein.libc6": "$libc_version", "org.skein.libs": "${libs[*]}"}},
 "rootfs": {"type": "layers", "diff_ids": ["sha256:$diff_id"]},
 "history": [{"created": "$created", "created_by": "deploy/docker/make-base.sh",
              "comment": "glibc $libc_version runtime ($arch)"}]}
EOF
cat >"$image/manifest.json" <<EOF
[{"Config": "config.json", "RepoTags": ["$tag"], "Layers": ["layer/layer.tar"]}]
EOF
tar -C "$image" -c . | docker load -q >/dev/null
echo "$tag"
