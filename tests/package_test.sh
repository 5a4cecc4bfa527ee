#!/usr/bin/env bash
# The installed package works for research code: install the build into a temporary prefix, build
# examples/embed out of tree with find_package(stylerf), and run it (a GEMM on the default device).
#   tests/package_test.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$1
src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cmake --install "$build" --prefix "$work/prefix" > "$work/install.log"
test -f "$work/prefix/lib/cmake/stylerf/stylerfConfig.cmake"
test -f "$work/prefix/include/stylerf/host/runtime.hpp"
ls "$work/prefix/share/stylerf/kernels/"*.cl > /dev/null
cmake -S "$src/examples/embed" -B "$work/embed" -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_BUILD_TYPE=Release > "$work/configure.log"
cmake --build "$work/embed" -j2 > "$work/build.log"
"$work/embed/embed"
echo "package: installed, found with find_package(stylerf), example built out of tree and run"
