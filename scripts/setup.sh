#!/usr/bin/env bash
# Installs the Debian packages the package builds against. Idempotent: does nothing
# (and needs no network) when everything is already installed.
set -euo pipefail

PACKAGES=(
  build-essential cmake pkg-config
  catkin python3-catkin-pkg python3-empy
  ros-base-dev pluginlib-dev librostest-dev python3-rostest ros-message-generation
  libroscpp-dev libstd-msgs-dev libsensor-msgs-dev libgeometry-msgs-dev libvisualization-msgs-dev
  libtf2-ros-dev libtf2-eigen-dev
  libeigen3-dev libceres-dev liboctomap-dev libpcl-dev libpcl-conversions-dev
  libassimp-dev libembree-dev libyaml-cpp-dev libpng-dev
  libgtest-dev libbenchmark-dev libcli11-dev nlohmann-json3-dev vcstool git
  libstd-srvs-dev libdiagnostic-updater-dev libtopic-tools-dev
  libdynamic-reconfigure-config-init-mutex-dev python3-dynamic-reconfigure rosbash
  python3-numpy python3-matplotlib python3-scipy
  # rostopic echo / rviz of what the package publishes
  python3-rostopic python3-std-msgs python3-sensor-msgs python3-geometry-msgs python3-visualization-msgs
  python3-diagnostic-msgs python3-std-srvs python3-genmsg
)
# rviz for demo.launch and the screenshot (scripts/screenshot.sh): scripts/setup.sh --rviz
if [ "${1:-}" = "--rviz" ]; then PACKAGES+=(rviz xvfb x11-apps imagemagick); fi

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
echo "setup: installing ${missing[*]}" >&2
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >&2
