#!/usr/bin/env bash
# Installs the Debian (bookworm) packages placedb needs to build, test and run
# its demo. Idempotent: packages already installed are skipped, and apt is
# not touched at all when nothing is missing.
set -euo pipefail

PACKAGES=(
  g++ cmake make pkg-config
  ninja-build            # the sanitizer trees of make check (CMakePresets.json)
  libopencv-dev          # ORB, FAST, SIFT, BFMatcher, image I/O
  libpng-dev             # PNG decoding with placedb's own error messages
  libcli11-dev           # command line
  libfmt-dev libspdlog-dev
  nlohmann-json3-dev     # manifests, reports
  libeigen3-dev          # poses
  libxxhash-dev          # XXH3 checksums of the database files (header-only use)
  libgtest-dev libgmock-dev
  libbenchmark-dev       # Google Benchmark
  python3                # demo and benchmark tables
  python3-matplotlib     # the experiment report's charts (placedb experiment)
  python3-numpy          # the report; the Python module's arrays
  pybind11-dev python3-dev  # the Python module (import placedb)
  chromium               # the report's browser test (headless)
  # ROS 1 (Debian's packages): the nodes, messages, bags, roslaunch. Not
  # needed with -DPLACEDB_WITH_ROS=OFF (PLACEDB_WITH_ROS=OFF ./install_deps.sh).
  ros:libroscpp-dev ros:libstd-msgs-dev ros:libsensor-msgs-dev ros:libgeometry-msgs-dev
  ros:libtf2-msgs-dev ros:libimage-transport-dev ros:libcv-bridge-dev ros:librosbag-storage-dev
  ros:ros-std-msgs ros:ros-geometry-msgs ros:python3-genmsg ros:python3-gencpp
  ros:python3-rosmaster ros:rosout ros:catkin ros:python3-roslaunch
  # rostopic and rosbag (the README's ROS section), genpy (placedb_msgs for
  # Python) and the Python messages rostopic decodes ours with.
  ros:python3-rostopic ros:python3-rosbag ros:python3-genpy
  # The bag reader's compressed chunks (bzip2, ROS's lz4 frames).
  ros:libbz2-dev ros:libroslz4-dev
  ros:python3-std-msgs ros:python3-geometry-msgs ros:python3-sensor-msgs
)

missing=()
for pkg in "${PACKAGES[@]}"; do
  [[ "$pkg" == \#* ]] && continue
  if [[ "$pkg" == ros:* ]]; then
    [[ "${PLACEDB_WITH_ROS:-ON}" == OFF ]] && continue
    pkg=${pkg#ros:}
  fi
  if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$pkg")
  fi
done

if [[ ${#missing[@]} -eq 0 ]]; then
  echo "install_deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

SUDO=""
if [[ $(id -u) -ne 0 ]]; then
  if command -v sudo >/dev/null 2>&1; then
    SUDO="sudo"
  else
    echo "install_deps: need root to install: ${missing[*]}" >&2
    echo "  run: apt-get install -y ${missing[*]}" >&2
    exit 1
  fi
fi

echo "install_deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
