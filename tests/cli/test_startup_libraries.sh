#!/usr/bin/env bash
# What each program loads at start-up (ldd): the launcher `csrbf` only the C and C++ runtimes; the
# serial program csrbf-cli no MPI, PETSc, HYPRE, Trilinos or MUMPS; and --version answered by the
# launcher alone, as the serial program would answer it; `csrbf morph` of an OpenFOAM case runs
# csrbf-morph, which loads none of VTK, CGNS, HDF5, Gmsh, assimp or the renderer's libraries, and a
# morph of any other format is handed to csrbf-cli with the same arguments. Neither loads CHOLMOD
# or its BLAS before a fit asks for them. `csrbf bench` runs csrbf-bench, beside csrbf-cli, which
# lists it in --help.
#   test_startup_libraries.sh LAUNCHER SERIAL_PROGRAM MORPH_PROGRAM SOURCE_DIR
set -euo pipefail
launcher=$1 serial=$2 morph=$3 source=$4
heavy='libmpi|libpetsc|libHYPRE|libtrilinos|libdmumps|libvtk|libtbb|libcholmod|libassimp'
if ldd "$launcher" | grep -E "$heavy"; then echo "the launcher loads the libraries above"; exit 1; fi
n=$(ldd "$launcher" | wc -l)
[ "$n" -le 8 ] || { ldd "$launcher"; echo "the launcher loads $n libraries (at most 8: the C and C++ runtimes)"; exit 1; }
if ldd "$serial" | grep -E 'libmpi|libpetsc|libHYPRE|libtrilinos|libdmumps|libopen-rte|libopen-pal'; then
  echo "the serial program loads MPI's or PETSc's libraries above"; exit 1
fi
want="$("$serial" --version)"
got="$("$launcher" --version)"
[ "$got" = "$want" ] || { echo "--version: the launcher says '$got', the program '$want'"; exit 1; }
[[ "$got" =~ ^csrbf\ [0-9]+\.[0-9]+\.[0-9]+ ]] || { echo "--version: '$got'"; exit 1; }
# Every other command goes to the program, with argv[0] as given (its messages name csrbf).
out=$("$launcher" no-such-command 2>&1 || true)
grep -q "csrbf" <<< "$out" || { echo "$out"; exit 1; }
if ldd "$morph" | grep -E 'libmpi|libpetsc|libvtk|libcgns|libhdf5|libgmsh|libassimp|libGL|libX11|libQt'; then
  echo "the morph program loads the libraries above"; exit 1
fi
# CHOLMOD and its BLAS are opened by the first fit that uses them (cholmod_loader.cpp), not at start.
for p in "$serial" "$morph"; do
  if ldd "$p" | grep -E 'libcholmod|libopenblas|libblas|liblapack|libgfortran|libmetis'; then
    echo "$p loads CHOLMOD or its BLAS at start"; exit 1
  fi
done
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# An OpenFOAM case: the morph program's work (its ldd above); a .vtu: csrbf-cli's, the same report.
"$launcher" morph "$source/examples/airfoil/case" --motion "$source/examples/airfoil/motion.json" -o "$tmp/foam" \
  --json --quiet > "$tmp/foam.json"
grep -q '"format": "openfoam"' "$tmp/foam.json" || { cat "$tmp/foam.json"; exit 1; }
# The bundled airfoil as a Gmsh file: csrbf-cli's work, handed over with the same arguments.
msh="$source/examples/airfoil/airfoil.msh"
"$launcher" morph "$msh" --motion "$source/examples/airfoil/motion.json" -o "$tmp/out.msh" --json --quiet > "$tmp/msh.json"
grep -q '"format": "msh"' "$tmp/msh.json" || { cat "$tmp/msh.json"; exit 1; }
# ... and a fit that asks for CHOLMOD gets it.
"$launcher" info --controls "$source/examples/fish.controls" --radius 0.3 --solver cholmod --json > "$tmp/info.json"
grep -q '"solver": "cholmod"' "$tmp/info.json" || { cat "$tmp/info.json"; exit 1; }
# Usage errors read the same from either program.
a=$("$launcher" morph "$msh" --radius -1 2>&1 || true)
b=$("$launcher" morph "$source/examples/airfoil/case" --radius -1 2>&1 || true)
[ -n "$a" ] && [ "$a" = "$b" ] || { echo "$a"; echo "$b"; exit 1; }
[ "$("$morph" morph --help | sed "s|$morph|P|")" = "$("$serial" morph --help | sed "s|$serial|P|")" ] ||
  { echo "morph --help differs"; exit 1; }
# `csrbf bench`: csrbf-bench's, with bench's --help naming csrbf; `csrbf --help` still lists it.
bench="$(dirname "$serial")/csrbf-bench"
[ -x "$bench" ] || { echo "no $bench"; exit 1; }
out=$("$launcher" bench --help)
grep -qF "Usage: $launcher bench [OPTIONS]" <<< "$out" || { echo "$out"; exit 1; }
out=$("$launcher" --help)
grep -qE '^  bench +Run a benchmark scenario' <<< "$out" || { echo "$out"; exit 1; }
out=$("$launcher" bench --scenario fish --json --seconds 0.01)
grep -q '"scenario":"fish"' <<< "$out" || { echo "$out"; exit 1; }
echo "launcher: $n libraries; morph program: $(ldd "$morph" | wc -l); serial program: $(ldd "$serial" | wc -l), no MPI or PETSc; --version: $got"
