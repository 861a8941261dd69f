# Sourced by make-base.sh and cross-build.sh: Debian's packages of another architecture
# (arm64 on an amd64 machine), from the mirror this machine's apt sources already name,
# through a private apt state kept under ~/.cache/skein/apt-ARCH (the machine's own apt
# configuration and architectures are left alone; a later run only asks the mirror what
# changed).
#
#   apt_foreign_init ARCH        reads ARCH's package lists; sets the array apt_opts for
#                                apt-get and apt-cache
#   apt_foreign_unpack DIR PKG…  downloads PKG… (of ARCH) and unpacks them under DIR

apt_foreign_init() {
  local arch=$1
  local apt_dir=${XDG_CACHE_HOME:-$HOME/.cache}/skein/apt-$arch
  mkdir -p "$apt_dir/lists/partial" "$apt_dir/archives/partial"
  : >"$apt_dir/status"
  apt_opts=(
    -o "Dir::State::Lists=$apt_dir/lists"
    -o "Dir::State::status=$apt_dir/status"
    -o "Dir::Cache=$apt_dir"
    -o "Dir::Cache::archives=$apt_dir/archives"
    -o "APT::Architecture=$arch"
    -o "APT::Architectures::=$arch"
    -o "Debug::NoLocking=1"
    -o "APT::Sandbox::User=root"
    -qq
  )
  echo "apt-foreign.sh: reading the $arch package lists of this machine's apt sources" >&2
  apt-get "${apt_opts[@]}" update
}

apt_foreign_unpack() {
  local dir=$1
  shift
  local debs
  debs=$(mktemp -d)
  (cd "$debs" && apt-get "${apt_opts[@]}" download "$@")
  mkdir -p "$dir"
  local deb
  for deb in "$debs"/*.deb; do dpkg-deb -x "$deb" "$dir"; done
  rm -rf "$debs"
}
