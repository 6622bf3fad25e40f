#!/bin/sh
# Build the Ceres peer (Debian/Ubuntu: apt-get install libceres-dev).
#   peers/ceres/build.sh [OUTPUT]   (default: peers/ceres/robimu_ceres)
set -e
here=$(cd "$(dirname "$0")" && pwd)
out=${1:-$here/robimu_ceres}
${CXX:-g++} -O3 -march=native -DNDEBUG -std=c++17 -I/usr/include/eigen3 \
  "$here/robimu_ceres.cc" -o "$out" -lceres -lglog -lgflags -lpthread
echo "built $out"
