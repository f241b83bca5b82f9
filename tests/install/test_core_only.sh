#!/usr/bin/env bash
# csrbf's core alone, as a game engine takes it:
# 1. a top-level configure with every optional part off defines csrbf::core and the core tests only
#    (test_core, and the engine's and the C API's consumers)
#    (configured, not built: step 2 builds the core alone, and the main build builds and runs the
#    core tests; building both here took 1.5 minutes of CI in a test that holds the whole machine);
# 2. a project that adds csrbf with add_subdirectory (nothing set) builds the core only and runs a fit,
#    with its own build type left unset.
# 3. that project's csrbf compiles optimised although it sets no build type, and its -fno-exceptions
#    engine consumer runs a frame within 1.5x of the same program in the Release build (BUILD_DIR);
# 4. FetchContent of csrbf's sources (an archive of the tracked files) configures the same way.
#   test_core_only.sh SOURCE_DIR BUILD_DIR
set -euo pipefail
src=$1 build=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cmake -S "$src" -B "$tmp/core" -G Ninja -DCSRBF_BUILD_IO=OFF -DCSRBF_BUILD_GLTF=OFF -DCSRBF_BUILD_RENDER=OFF -DCSRBF_BUILD_VTK=OFF \
  -DCSRBF_BUILD_PYTHON=OFF -DCSRBF_BUILD_APPS=OFF -DCSRBF_BUILD_GUI=OFF -DCSRBF_BUILD_BENCH=OFF \
  -DCSRBF_BUILD_TESTS=ON -DCMAKE_DISABLE_FIND_PACKAGE_VTK=ON -DCMAKE_DISABLE_FIND_PACKAGE_MPI=ON \
  -DCMAKE_DISABLE_FIND_PACKAGE_assimp=ON > "$tmp/core.log" 2>&1 || { cat "$tmp/core.log"; exit 1; }
programs=$(cd "$tmp/core" && ninja -t targets all | grep -oE '^bin/[^:]+' | sort -u | tr '\n' ' ')
[ "$programs" = "bin/c_api_consumer bin/engine_consumer bin/test_core " ] ||
  { echo "a core-only configure defines other programs than test_core, engine_consumer and c_api_consumer: $programs"; exit 1; }
echo "core-only configure: $programs"

cmake -S "$src/tests/install/subdirectory" -B "$tmp/sub" -G Ninja -DCSRBF_SOURCE_DIR="$src" \
  -DCMAKE_DISABLE_FIND_PACKAGE_VTK=ON -DCMAKE_DISABLE_FIND_PACKAGE_MPI=ON \
  -DCMAKE_DISABLE_FIND_PACKAGE_assimp=ON > "$tmp/sub.log" 2>&1 || { cat "$tmp/sub.log"; exit 1; }
grep -q '^CMAKE_BUILD_TYPE:STRING=$' "$tmp/sub/CMakeCache.txt" || { echo "add_subdirectory(csrbf) set the build type"; exit 1; }
grep -q "sets no CMAKE_BUILD_TYPE: csrbf's libraries compile optimised" "$tmp/sub.log" ||
  { echo "add_subdirectory(csrbf) without a build type did not say how it compiles"; exit 1; }
cmake --build "$tmp/sub" --parallel "$(nproc)" --target consumer engine > "$tmp/sub-build.log" 2>&1 || { tail -50 "$tmp/sub-build.log"; exit 1; }
echo -n "add_subdirectory consumer: "
"$tmp/sub/consumer"
echo -n "add_subdirectory engine consumer (-fno-exceptions): "
"$tmp/sub/engine"
# csrbf's own objects compiled -O3 -DNDEBUG, the parent's own without.
# (Listed into files first: `grep -q` leaves a pipe early, and under pipefail the writer's SIGPIPE
# failed the test by chance.)
(cd "$tmp/sub" && ninja -t commands csrbf/src/core/libcsrbf_core.a) > "$tmp/sub-commands.txt"
grep 'space_map.cpp' "$tmp/sub-commands.txt" | grep -- '-O3.*-DNDEBUG\|-DNDEBUG.*-O3' > /dev/null ||
  { echo "csrbf's core was not compiled optimised under a parent without a build type"; exit 1; }
# A frame, best of 7, each build's program run alternately three times (the machine is shared).
sub_ms=() rel_ms=()
for k in 1 2 3; do
  sub_ms+=("$("$tmp/sub/engine" --time | awk '{print $2}')")
  rel_ms+=("$("$build/bin/engine_consumer" --time | awk '{print $2}')")
done
ratio=$(printf '%s\n' "${sub_ms[@]}" | sort -g | head -n1 | awk -v r="$(printf '%s\n' "${rel_ms[@]}" | sort -g | head -n1)" '{printf "%.2f", $1 / r}')
echo "frame: add_subdirectory without a build type ${sub_ms[*]} ms, Release ${rel_ms[*]} ms: ratio of the best $ratio"
awk -v r="$ratio" 'BEGIN { exit !(r <= 1.5) }' || { echo "add_subdirectory's frame is more than 1.5x Release's"; exit 1; }

# FetchContent from an archive of the tracked (and new, not ignored) files: configures, defines csrbf::core.
if git -C "$src" rev-parse --git-dir > /dev/null 2>&1; then
  (cd "$src" && git ls-files -co --exclude-standard -z | xargs -0 -I{} sh -c 'test -f "{}" && printf "%s\0" "{}"' |
    tar --null -T - -czf "$tmp/csrbf.tar.gz")
  cmake -S "$src/tests/install/subdirectory" -B "$tmp/fetch" -G Ninja -DCSRBF_FETCH=ON \
    -DCSRBF_SOURCE_ARCHIVE="$tmp/csrbf.tar.gz" -DCMAKE_DISABLE_FIND_PACKAGE_VTK=ON -DCMAKE_DISABLE_FIND_PACKAGE_MPI=ON \
    -DCMAKE_DISABLE_FIND_PACKAGE_assimp=ON > "$tmp/fetch.log" 2>&1 || { cat "$tmp/fetch.log"; exit 1; }
  (cd "$tmp/fetch" && ninja -t targets all) > "$tmp/fetch-targets.txt"
  grep '^consumer:' "$tmp/fetch-targets.txt" > /dev/null || { echo "FetchContent(csrbf) defines no consumer"; exit 1; }
  echo "FetchContent consumer: configured"
fi
