#!/usr/bin/env bash
# Prepares the ROS 2 Jazzy peers of the tests (tests/e2e_ros2.rs), idempotently, and
# prints nothing when all is in place:
#   1. cmake and a C/C++ compiler (Debian's), and Python's headers, if missing;
#   2. .venv-ros2: rclpy on Fast DDS and ROS 2's interface generators from the
#      ros-jazzy-* wheels on PyPI (tests/peers/ros2/requirements.txt), and
#      .venv-ros2-kilted: Kilted's rclpy on Fast DDS 3 with the standard messages alone
#      (requirements-kilted.txt; nothing is built for it);
#   3. ros2/skein_msgs and the tests' tf2_msgs and rtcm_msgs built with
#      rosidl_generate_interfaces and installed into .venv-ros2/ws/install, again
#      whenever a file of one of the packages, or the requirements, change;
#   4. .venv-ros2/skein.env: the environment a Jazzy peer runs in (KEY=VALUE lines; a
#      Kilted peer needs none: its wheels' .pth sets LD_LIBRARY_PATH).
# tests/run.sh runs it before the tests; the tests run it too (once per test process),
# so `cargo test --test e2e_ros2` works on its own. A lock keeps two runs apart.
set -euo pipefail
root="$(cd "$(dirname "$0")/../../.." && pwd)"
cd "$root"
venv="$root/.venv-ros2"
req="tests/peers/ros2/requirements.txt"
kilted="$root/.venv-ros2-kilted"
req_kilted="tests/peers/ros2/requirements-kilted.txt"
packages=(ros2/skein_msgs tests/peers/ros2/tf2_msgs tests/peers/ros2/rtcm_msgs)

exec 9>"$root/.venv-ros2.lock"
flock 9

apt_install() {
  local sudo=""
  [ "$(id -u)" = 0 ] || sudo="sudo"
  echo "tests/peers/ros2/setup.sh: installing $*" >&2
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "$@" >/dev/null
}
missing=()
command -v cmake >/dev/null 2>&1 || missing+=(cmake)
command -v c++ >/dev/null 2>&1 || missing+=(g++)
command -v make >/dev/null 2>&1 || missing+=(make)
# The Python extension of the generated messages compiles against Python.h.
if ! python3 -c 'import os, sys, sysconfig
sys.exit(not os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")))'; then
  missing+=(python3-dev)
fi
[ ${#missing[@]} -eq 0 ] || apt_install "${missing[@]}"

# `make_venv DIR REQUIREMENTS`: DIR a venv made from REQUIREMENTS (idempotent: a copy of
# them in DIR/.skein-requirements says what it was made from); true when it was made now.
make_venv() {
  if [ -x "$1/bin/python" ] && cmp -s "$2" "$1/.skein-requirements"; then
    return 1
  fi
  local started
  started=$(date +%s)
  echo "tests/peers/ros2/setup.sh: preparing $(basename "$1") from $2" >&2
  rm -rf "$1"
  python3 -m venv "$1" || exit 1
  "$1/bin/python" -m pip install --quiet --disable-pip-version-check -r "$2" || exit 1
  echo "tests/peers/ros2/setup.sh: $(basename "$1") installed in $(($(date +%s) - started)) s" >&2
}

# Kilted's venv downloads while Jazzy's is made and its packages build.
(
  if make_venv "$kilted" "$req_kilted"; then
    cp "$req_kilted" "$kilted/.skein-requirements"
  fi
) &
kilted_pid=$!

if make_venv "$venv" "$req"; then
  # The wheels' exported CMake targets name the include directories of the machine they
  # were built on (/opt/python/cp311-cp311/..., the manylinux image's Python), and CMake
  # refuses an imported target whose include directory does not exist. Point them at
  # this interpreter's headers and the venv's numpy instead.
  pyinc=$("$venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
  npinc=$("$venv/bin/python" -c 'import numpy; print(numpy.get_include())')
  grep -rlE '/opt/python/cp3[0-9]+-cp3[0-9]+/' "$venv/share" --include='*.cmake' |
    xargs -r sed -i -E \
      -e "s#/opt/python/cp3[0-9]+-cp3[0-9]+/include/python3\.[0-9]+#$pyinc#g" \
      -e "s#/opt/python/cp3[0-9]+-cp3[0-9]+/lib/python3\.[0-9]+/site-packages/numpy/_core/include#$npinc#g"
  cp "$req" "$venv/.skein-requirements"
fi

ws="$venv/ws"
install="$ws/install"
stamp=$( (cat "$req"; find "${packages[@]}" -type f -print0 | sort -z | xargs -0 sha256sum) | sha256sum | cut -d' ' -f1)
if ! [ -f "$ws/.skein-stamp" ] || [ "$(cat "$ws/.skein-stamp")" != "$stamp" ]; then
  echo "tests/peers/ros2/setup.sh: building ${packages[*]} with rosidl" >&2
  started=$(date +%s)
  rm -rf "$ws"
  mkdir -p "$ws"
  for pkg in "${packages[@]}"; do
    name=$(basename "$pkg")
    # ament finds the generators and the typesupports through the ament index of every
    # prefix on AMENT_PREFIX_PATH: the venv (the wheels install into it) and ours.
    AMENT_PREFIX_PATH="$install:$venv" cmake -S "$pkg" -B "$ws/build/$name" \
      -DCMAKE_PREFIX_PATH="$install;$venv" -DCMAKE_INSTALL_PREFIX="$install" \
      -DPython3_EXECUTABLE="$venv/bin/python" -DBUILD_TESTING=OFF >"$ws/build-$name.log" 2>&1 ||
      { cat "$ws/build-$name.log" >&2; exit 1; }
    AMENT_PREFIX_PATH="$install:$venv" cmake --build "$ws/build/$name" -j "$(nproc)" \
      >>"$ws/build-$name.log" 2>&1 || { tail -50 "$ws/build-$name.log" >&2; exit 1; }
    cmake --install "$ws/build/$name" >>"$ws/build-$name.log" 2>&1 ||
      { tail -20 "$ws/build-$name.log" >&2; exit 1; }
  done
  site=$(echo "$install"/lib/python3*/site-packages)
  {
    echo "PYTHONPATH=$site"
    echo "LD_LIBRARY_PATH=$install/lib"
    echo "AMENT_PREFIX_PATH=$install:$venv"
    echo "RMW_IMPLEMENTATION=rmw_fastrtps_cpp"
  } >"$venv/skein.env"
  echo "$stamp" >"$ws/.skein-stamp"
  echo "tests/peers/ros2/setup.sh: built in $(($(date +%s) - started)) s" >&2
fi

wait "$kilted_pid"
