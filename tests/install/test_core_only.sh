#!/usr/bin/env bash
# csrbf's core alone, as a game engine takes it:
# 1. a top-level configure with every optional part off defines csrbf::core and the core tests only
#    (configured, not built: step 2 builds the core alone, and the main build builds and runs the
#    core tests; building both here took 1.5 minutes of CI in a test that holds the whole machine);
# 2. a project that adds csrbf with add_subdirectory (nothing set) builds the core only and runs a fit,
#    with its own build type left unset.
#   test_core_only.sh SOURCE_DIR
set -euo pipefail
src=$1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cmake -S "$src" -B "$tmp/core" -G Ninja -DCSRBF_BUILD_IO=OFF -DCSRBF_BUILD_RENDER=OFF -DCSRBF_BUILD_VTK=OFF \
  -DCSRBF_BUILD_PYTHON=OFF -DCSRBF_BUILD_APPS=OFF -DCSRBF_BUILD_GUI=OFF -DCSRBF_BUILD_BENCH=OFF \
  -DCSRBF_BUILD_TESTS=ON -DCMAKE_DISABLE_FIND_PACKAGE_VTK=ON -DCMAKE_DISABLE_FIND_PACKAGE_MPI=ON \
  -DCMAKE_DISABLE_FIND_PACKAGE_assimp=ON > "$tmp/core.log" 2>&1 || { cat "$tmp/core.log"; exit 1; }
programs=$(cd "$tmp/core" && ninja -t targets all | grep -oE '^bin/[^:]+' | sort -u | tr '\n' ' ')
[ "$programs" = "bin/test_core " ] || { echo "a core-only configure defines more programs than test_core: $programs"; exit 1; }
echo "core-only configure: $programs"

cmake -S "$src/tests/install/subdirectory" -B "$tmp/sub" -G Ninja -DCSRBF_SOURCE_DIR="$src" \
  -DCMAKE_DISABLE_FIND_PACKAGE_VTK=ON -DCMAKE_DISABLE_FIND_PACKAGE_MPI=ON \
  -DCMAKE_DISABLE_FIND_PACKAGE_assimp=ON > "$tmp/sub.log" 2>&1 || { cat "$tmp/sub.log"; exit 1; }
grep -q '^CMAKE_BUILD_TYPE:STRING=$' "$tmp/sub/CMakeCache.txt" || { echo "add_subdirectory(csrbf) set the build type"; exit 1; }
cmake --build "$tmp/sub" --parallel "$(nproc)" > "$tmp/sub-build.log" 2>&1 || { tail -50 "$tmp/sub-build.log"; exit 1; }
echo -n "add_subdirectory consumer: "
"$tmp/sub/consumer"
