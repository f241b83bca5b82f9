#!/usr/bin/env bash
# The tests mirror include/ (issue 50): every public header include/csrbf/<dir>/<name>.hpp (or .h) has
# its test file tests/<dir>/test_<name>.cpp (<dir>: core for the top level), built by
# tests/CMakeLists.txt. detail/ folders are not public. A header tested under another name is mapped
# below, with the reason. Prints each header without its test and exits 1; a mapping whose header is
# gone fails too.
#   check-test-mirror.sh [INCLUDE_DIR [TESTS_DIR]]   (default: the source tree's include/ and tests/)
set -euo pipefail
src=$(cd "$(dirname "$0")/.." && pwd)
include=${1:-$src/include}
tests=${2:-$src/tests}

# Header (relative to include/csrbf) -> test file (relative to tests/), and why it is not the mirror.
declare -A mapped=(
  # The C API is judged from C: a C11 program built with -Werror against `csrbf deform`.
  [csrbf.h]=capi/test_c_api.sh
  # The exporter's tests read back whole scenes (csrbf::io) and run render's exporter (VTK's
  # texture coordinates): test_export, apart from the gltf component's own test_gltf_component.
  [gltf/export.hpp]=export/test_gltf.cpp
  # The MPI runtime is test_mpi's main: it starts MPI and PETSc once for every test, under 1-4 ranks.
  [mpi/runtime.hpp]=mpi/test_mpi.cpp
  # VTK's naming (vtkCSRBFTransform): the test keeps the project's.
  [vtk/vtkCSRBFTransform.h]=vtk/test_vtk_transform.cpp
  # Forwarding headers (csrbf::render's old names for csrbf::gltf's), checked together.
  [render/gltf_export.hpp]=render/test_gltf_names.cpp
  [render/gltf_meshopt.hpp]=render/test_gltf_names.cpp
  [render/gltf_runtime.hpp]=render/test_gltf_names.cpp
)

missing=0
while IFS= read -r header; do
  rel=${header#"$include/csrbf/"}
  if [[ -n ${mapped[$rel]+set} ]]; then
    test=${mapped[$rel]}
  else
    dir=$(dirname "$rel")
    [ "$dir" = . ] && dir=core
    name=$(basename "$rel")
    test=$dir/test_${name%.*}.cpp
  fi
  if [ ! -f "$tests/$test" ]; then
    echo "check-test-mirror: include/csrbf/$rel has no test: tests/$test is missing"
    missing=1
  elif ! grep -qE "(^|[[:space:](/])${test//./\\.}([[:space:])]|\$)" "$tests/CMakeLists.txt"; then
    echo "check-test-mirror: include/csrbf/$rel: tests/$test is not in tests/CMakeLists.txt"
    missing=1
  fi
done < <(find "$include/csrbf" \( -name detail -prune \) -o -type f \( -name '*.hpp' -o -name '*.h' \) -print | sort)

for rel in "${!mapped[@]}"; do
  if [ ! -f "$include/csrbf/$rel" ]; then
    echo "check-test-mirror: the mapping of include/csrbf/$rel names a header that is gone"
    missing=1
  fi
done

if [ "$missing" -ne 0 ]; then exit 1; fi
echo "check-test-mirror: every public header under include/csrbf has its test"
