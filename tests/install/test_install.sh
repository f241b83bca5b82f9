#!/usr/bin/env bash
# cmake --install into a temporary prefix, then: the programs, config files and Python module are in
# place; a consumer project per component builds against the installed tree and runs (the core's
# with VTK, MPI and assimp disabled: find_package(csrbf) must not look for them); the offline wheel
# installs and imports.
#   test_install.sh BUILD_DIR SOURCE_DIR PYTHON
set -euo pipefail
build=$1 src=$2 python=$3
# The mpi consumer starts MPI alone (a singleton); CI runs as root, which Open MPI refuses unless told.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cmake --install "$build" --prefix "$tmp/prefix" > "$tmp/install.log"
for f in bin/csrbf bin/csrbf-picker bin/csrbf-composer libexec/csrbf/csrbf-cli libexec/csrbf/csrbf-bench; do
  test -x "$tmp/prefix/$f" || { echo "missing $f"; exit 1; }
done
# The installed launcher finds the program it runs from its own place.
"$tmp/prefix/bin/csrbf" --version | grep -q '^csrbf ' || { echo "installed csrbf --version failed"; exit 1; }
"$tmp/prefix/bin/csrbf" info --controls "$src/examples/fish.controls" --radius 0.3 > /dev/null ||
  { echo "installed csrbf info failed"; exit 1; }
grep -q '"scenario":"fish"' <<< "$("$tmp/prefix/bin/csrbf" bench --scenario fish --json --seconds 0.01)" ||
  { echo "installed csrbf bench failed"; exit 1; }
for f in lib/cmake/csrbf/csrbfConfig.cmake lib/cmake/csrbf/csrbfConfigVersion.cmake \
         lib/cmake/csrbf/csrbf-core-targets.cmake lib/cmake/csrbf/csrbf-anim-targets.cmake \
         lib/cmake/csrbf/csrbf-io-targets.cmake lib/cmake/csrbf/csrbf-render-targets.cmake \
         lib/cmake/csrbf/csrbf-gltf-targets.cmake include/csrbf/gltf/runtime.hpp include/csrbf/gltf/glb.hpp lib/libcsrbf_gltf.a \
         include/csrbf/csrbf.h include/csrbf/units.hpp lib/pkgconfig/csrbf.pc \
         lib/cmake/csrbf/csrbf-vtk-targets.cmake lib/cmake/csrbf/csrbf-morph-targets.cmake lib/cmake/csrbf/FindCGNS.cmake \
         lib/cmake/csrbf/csrbf-mpi-targets.cmake include/csrbf/mpi/distributed.hpp lib/libcsrbf_mpi.a \
         include/csrbf/space_map.hpp include/csrbf/version.hpp include/csrbf/vtk/vtkCSRBFTransform.h include/csrbf/anim/scene.hpp \
         include/csrbf/morph/morph.hpp lib/libcsrbf_morph.a \
         lib/libcsrbf_core.a lib/libcsrbf_vtk.a; do
  test -f "$tmp/prefix/$f" || { echo "missing $f"; exit 1; }
done
# The three.js plugin, made at build time with the shader's one source inside it, beside that source.
web="$tmp/prefix/share/csrbf/web"
grep -q 'void csrbfDeform(' "$web/csrbf_deformation.js" && ! grep -q '@CSRBF_GLSL@' "$web/csrbf_deformation.js" &&
  test -f "$web/csrbf_deformation.glsl" || { echo "the installed three.js plugin lacks its shader"; exit 1; }
# The licence: installed beside the documentation and named by the CMake package.
grep -q '^BSD 3-Clause License' "$tmp/prefix/share/doc/csrbf/LICENSE" || { echo "LICENSE not installed"; exit 1; }
grep -q 'set(csrbf_LICENSE "BSD-3-Clause")' "$tmp/prefix/lib/cmake/csrbf/csrbfConfig.cmake" ||
  { echo "csrbfConfig.cmake does not name the licence"; exit 1; }
package=$(find "$tmp/prefix/lib" -name '__init__.py' -path '*dist-packages/csrbf/*' | head -n1)
test -n "$package" || { echo "missing the Python package under lib/python3.*/dist-packages/csrbf"; exit 1; }
module=$(dirname "$package")  # the package directory; its parent goes on PYTHONPATH
PYTHONPATH=$(dirname "$module") "$python" -c "import csrbf, numpy as np; m = csrbf.SpaceMap(np.eye(3), np.eye(3) + 0.1, 2.0); assert abs(m(np.eye(3))[0, 0] - 1.1) < 1e-12"
# The file functions are a second extension (csrbf._io), installed beside csrbf._core and loaded on first use.
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n' > "$tmp/tri.obj"
PYTHONPATH=$(dirname "$module") "$python" -c "
import sys, csrbf
assert 'csrbf._io' not in sys.modules
p, f = csrbf.read_mesh(sys.argv[1])
assert p.shape == (3, 3) and f == [[0, 1, 2]], (p, f)
try:
    csrbf.read_mesh(sys.argv[1] + '.missing.obj')
    raise SystemExit('no FileError')
except csrbf.FileError:
    pass" "$tmp/tri.obj"
vtkpkg=$(dirname "$module")/csrbf_vtk
if [ -f "$vtkpkg/__init__.py" ]; then
  PYTHONPATH=$(dirname "$module") "$python" -c "import vtk; from csrbf_vtk import vtkCSRBFTransform; t = vtkCSRBFTransform(); t.SetRadius(2.0); assert t.GetRadius() == 2.0"
  echo "installed: csrbf_vtk (vtkCSRBFTransform for VTK's Python)"
fi
echo "installed: programs, headers, libraries, CMake config and version, Python module ($module)"

# The core consumer's configure must not reach VTK, MPI or assimp; nor may the exported core name
# CHOLMOD at all (csrbf_core opens it at run time, on a fit's first use: cholmod_loader.cpp).
if grep -qi 'cholmod' "$tmp/prefix/lib/cmake/csrbf/csrbf-core-targets.cmake"; then
  echo "csrbf-core-targets.cmake names CHOLMOD"; exit 1
fi
for c in core engine anim io morph morph_formats mpi gltf render vtk; do
  extra=()
  if [ "$c" = core ] || [ "$c" = engine ] || [ "$c" = gltf ]; then
    extra=(-DCMAKE_DISABLE_FIND_PACKAGE_VTK=ON -DCMAKE_DISABLE_FIND_PACKAGE_MPI=ON -DCMAKE_DISABLE_FIND_PACKAGE_assimp=ON)
  fi
  cmake -S "$src/tests/install/consumers" -B "$tmp/consumer-$c" -G Ninja -DCMAKE_BUILD_TYPE=Release \
    -DCSRBF_COMPONENT=$c "${extra[@]}" -DCMAKE_PREFIX_PATH="$tmp/prefix" > "$tmp/consumer-$c.log" 2>&1 ||
    { cat "$tmp/consumer-$c.log"; exit 1; }
  cmake --build "$tmp/consumer-$c" > "$tmp/consumer-$c-build.log" 2>&1 || { cat "$tmp/consumer-$c-build.log"; exit 1; }
  echo -n "consumer of csrbf::$c: "
  "$tmp/consumer-$c/consumer"
  if [ "$c" = gltf ] && ldd "$tmp/consumer-$c/consumer" | grep -Ei 'libvtk|libX11|libassimp|libmpi'; then
    echo "the consumer of csrbf::gltf loads the libraries above"; exit 1
  fi
done

# The C API from C alone: deform_fish.c (tests/capi) in a CMake project of the C language only, and
# with the installed csrbf.pc and the system's C compiler, as a build without CMake does.
cmake -S "$src/tests/install/consumer-c" -B "$tmp/consumer-c" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCSRBF_SOURCE_DIR="$src" -DCMAKE_PREFIX_PATH="$tmp/prefix" > "$tmp/consumer-c.log" 2>&1 || { cat "$tmp/consumer-c.log"; exit 1; }
cmake --build "$tmp/consumer-c" > "$tmp/consumer-c-build.log" 2>&1 || { cat "$tmp/consumer-c-build.log"; exit 1; }
flags=$(PKG_CONFIG_PATH="$tmp/prefix/lib/pkgconfig" pkg-config --cflags --libs csrbf)
# shellcheck disable=SC2086
cc -std=c11 -Wall -Wextra -Werror -pedantic "$src/tests/capi/deform_fish.c" -o "$tmp/deform_fish-pc" $flags ||
  { echo "cc with pkg-config's flags ($flags) failed"; exit 1; }
for p in "$tmp/consumer-c/consumer" "$tmp/deform_fish-pc"; do
  "$p" "$src/examples/fish.obj" "$src/examples/fish.controls" 0.3 > "$p.obj"
  [ "$(grep -c '^v ' "$p.obj")" = 977 ] || { echo "$p did not deform the fish's 977 vertices"; exit 1; }
done
cmp "$tmp/consumer-c/consumer.obj" "$tmp/deform_fish-pc.obj" ||
  { echo "the C consumers built by CMake and by pkg-config differ"; exit 1; }
echo "C API: a C-only CMake project and cc with pkg-config ($flags) deform the fish"

# The default build made the wheel (python/CMakeLists.txt): this test builds nothing in the build folder.
wheel=$(ls -t "$build"/dist/csrbf-*.whl 2> /dev/null | head -n1)
[ -n "$wheel" ] || { echo "no wheel in $build/dist: build the project first"; exit 1; }
# As a Python user installs it: a venv that sees Debian's numpy, pip offline, the wheel's stated
# dependency (numpy) resolved against it (no --no-deps), the type stubs beside the module.
"$python" -c "import sys, zipfile; z = zipfile.ZipFile(sys.argv[1]); sys.exit(not any(l.startswith('Requires-Dist: numpy') for n in z.namelist() if n.endswith('.dist-info/METADATA') for l in z.read(n).decode().splitlines()))" "$wheel" || { echo "the wheel does not state numpy"; exit 1; }
"$python" -c "import sys, zipfile; z = zipfile.ZipFile(sys.argv[1]); m = [z.read(n).decode() for n in z.namelist() if n.endswith('.dist-info/METADATA')][0]; sys.exit(not ('License: BSD-3-Clause' in m.splitlines() and any(n.endswith('LICENSE') for n in z.namelist())))" "$wheel" ||
  { echo "the wheel's metadata does not name BSD-3-Clause or carry LICENSE"; exit 1; }
"$python" -m venv --system-site-packages "$tmp/venv"
(cd "$tmp" && PYTHONPATH= PIP_ROOT_USER_ACTION=ignore "$tmp/venv/bin/python" -m pip install --disable-pip-version-check \
  --no-index --quiet "$wheel")
(cd "$tmp" && PYTHONPATH= TMPDIR_TEST="$tmp" "$tmp/venv/bin/python" - <<'PY'
import multiprocessing, os, pickle, site
import numpy as np
import csrbf
assert csrbf.__file__.startswith(site.getsitepackages()[0]), csrbf.__file__
for f in ("_interpolate.py", "_core.pyi", "_io.pyi", "py.typed"):
    assert os.path.exists(os.path.join(site.getsitepackages()[0], "csrbf", f)), f
xy = np.random.default_rng(0).random((2000, 2))
s = csrbf.Interpolator(xy, np.sin(4 * xy[:, 0]), neighbors=20)
t = pickle.loads(pickle.dumps(s))
with multiprocessing.Pool(2) as pool:
    got = pool.map(t, [xy[:10], xy[10:20]])
assert np.allclose(np.concatenate(got), np.sin(4 * xy[:20, 0]), atol=1e-9)
points, faces = csrbf.read_mesh(os.path.join(os.environ["TMPDIR_TEST"], "tri.obj"))  # csrbf._io, from the wheel
assert points.shape == (3, 3) and faces == [[0, 1, 2]]
print("wheel", csrbf.__version__, "in a venv:", repr(s))
PY
)

# `pip install .` from the sources, as from a checkout: pip's isolated build with the in-tree backend
# (pyproject.toml), offline, into a fresh venv that sees Debian's numpy. The build folder is this one
# (already built: the backend only packs); a build from nothing is what `pip install .` does without it.
"$python" -m venv --system-site-packages "$tmp/venv-source"
(cd "$src" && PYTHONPATH= PIP_ROOT_USER_ACTION=ignore "$tmp/venv-source/bin/python" -m pip install \
  --disable-pip-version-check --no-index --quiet --config-settings build-dir="$build" . ) ||
  { echo "pip install . failed"; exit 1; }
(cd "$tmp" && PYTHONPATH= "$tmp/venv-source/bin/python" - <<'PY'
import os, site
import numpy as np
import csrbf
(path,) = csrbf.__path__
assert path == os.path.join(site.getsitepackages()[0], "csrbf") and os.path.isfile(os.path.join(path, "_interpolate.py")), path
s = csrbf.Interpolator(np.eye(3)[:, :2], np.arange(3.0), radius=2.0)
assert np.allclose(s(np.eye(3)[:, :2]), np.arange(3.0), atol=1e-12)
print("pip install . into a venv:", path)
PY
) || exit 1
echo "a consumer per component built with find_package(csrbf); wheel and pip install . install offline into a venv"
