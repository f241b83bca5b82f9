#!/usr/bin/env bash
# What each program loads at start-up (ldd): the launcher `csrbf` only the C and C++ runtimes; the
# serial program csrbf-cli no MPI, PETSc, HYPRE, Trilinos or MUMPS; and --version answered by the
# launcher alone, as the serial program would answer it.
#   test_startup_libraries.sh LAUNCHER SERIAL_PROGRAM
set -euo pipefail
launcher=$1 serial=$2
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
echo "launcher: $n libraries; serial program: $(ldd "$serial" | wc -l), no MPI or PETSc; --version: $got"
