#!/usr/bin/env bash
# The single list of Debian 12 packages csrbf needs to build, test and run.
# Non-interactive and idempotent: safe to run twice. Run as root (or with sudo available).
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config
  libeigen3-dev          # core: dense/sparse linear algebra (core's only required dependency)
  libtbb-dev             # core: parallel loops over vertices
  libassimp-dev          # io: STL and glTF meshes
  nlohmann-json3-dev     # io/cli: JSON output
  libmeshoptimizer-dev   # render: csrbf export --meshopt (EXT_meshopt_compression)
  libcli11-dev           # cli: argument parsing
  libgtest-dev libgmock-dev   # tests
  libbenchmark-dev       # bench/
  libsuitesparse-dev     # core (optional): CHOLMOD for large fits; solvers benchmark
  libopenblas0-pthread   # BLAS under CHOLMOD (replaces reference BLAS by alternatives): 3-5x faster big fits
  libvtk9-dev            # render (csrbf animate), the `peers` benchmark, tests against vtkKochanekSpline
  libvtk9-qt-dev qtbase5-dev   # csrbf-picker (Qt 5 widgets + VTK's QVTKOpenGLNativeWidget)
  xvfb xauth             # csrbf animate without a display starts a private Xvfb; GUI tests start their own (tests/with-xvfb.sh)
  libx11-dev             # render: checks that a DISPLAY opens before VTK uses it (XOpenDisplay)
  ffmpeg                 # csrbf animate writes movies through the ffmpeg program; tests read them with ffprobe
  pybind11-dev python3-dev python3-numpy   # the Python module (Debian's /usr/bin/python3)
  python3-vtk9           # vtkCSRBFTransform wrapped for VTK's Python (VTK's wrapping tools and runtime)
  python3-scipy python3-pip python3-setuptools python3-wheel   # Python tests: SciPy; the offline wheel
  python3-matplotlib python3-venv   # bench/python_interpolation.py's plot; the wheel tried in a venv (tests/install)
  clang libclang-rt-14-dev   # scripts/fuzz.sh: libFuzzer targets (not needed to build or test)
  clang-format           # scripts/check-format.sh: CI checks the tree's formatting
  universal-ctags        # scripts/function-lengths.sh: the test function_lengths measures every function
  gnuplot-nox            # scripts/plot_performance.sh: docs/performance.png
  zlib1g-dev             # morph: gzip'd OpenFOAM meshes
  libgmsh-dev libcgns-dev   # morph: Gmsh .msh and CGNS meshes
  python3-gmsh python3-meshio python3-h5py gmsh   # tests: Gmsh, meshio (h5py: its CGNS reader) read the morphed meshes
  openfoam openfoam-examples   # tests: checkMesh, blockMesh, foamFormatConvert judge `csrbf morph`; the airFoil2D and pitzDaily tutorials
  libopenmpi-dev openmpi-bin petsc-dev   # csrbf::mpi: `mpirun csrbf deform|morph`, PETSc's MUMPS Cholesky and CG
  nodejs blender chromium   # tests: the Khronos glTF validator (npm, below), Blender's importer, the page in a browser
)
# npm: Debian's package, unless the machine's Node.js already brings its own (NodeSource's does, and
# Debian's npm then cannot be installed beside it).
if ! command -v npm > /dev/null 2>&1; then
  packages+=(npm)
fi

# npm packages, into the build folder (never globally): the Khronos glTF validator for the tests;
# three.js (a current release) and esbuild, which bundles it with web/csrbf_deformation.js into the
# script of the page of `csrbf export --html` when csrbf is built.
npm_packages=(gltf-validator@2.0.0-dev.3.10 three@0.187.0 esbuild@0.28.2)

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  SUDO="sudo"
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

# apt-get update first, always, as the package lists of a fresh machine may be empty or stale.
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
if [ "${#missing[@]}" -gt 0 ]; then
  echo "install-deps: installing ${missing[*]}"
  $SUDO apt-get install -y -qq --no-install-recommends "${packages[@]}"
else
  echo "install-deps: all ${#packages[@]} packages already installed"
fi

# The npm packages, into build/npm of this checkout (the tests look there: CSRBF_NODE_MODULES).
root="$(cd "$(dirname "$0")/.." && pwd)"
npm_missing=()
for p in "${npm_packages[@]}"; do
  name="${p%@*}"
  version="${p##*@}"
  if ! grep -q "\"version\": \"$version\"" "$root/build/npm/node_modules/$name/package.json" 2>/dev/null; then
    npm_missing+=("$p")
  fi
done
if [ "${#npm_missing[@]}" -gt 0 ]; then
  mkdir -p "$root/build/npm"
  echo "install-deps: npm install ${npm_packages[*]} into $root/build/npm"
  npm install --prefix "$root/build/npm" --no-audit --no-fund --loglevel=error "${npm_packages[@]}"
else
  echo "install-deps: npm packages already in $root/build/npm"
fi
