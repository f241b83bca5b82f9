#!/usr/bin/env bash
# Builds everything with AddressSanitizer and UndefinedBehaviorSanitizer (CSRBF_SANITIZE=ON) in
# build-asan/ and runs the whole test suite there. Not in this build: the Python module (Debian's
# python3 is not built with ASan, so an instrumented module cannot load into it), the benchmarks, and
# the install test (it installs and builds a consumer, which the sanitizers add nothing to), and
# csrbf::mpi (Open MPI and PETSc are not built with the sanitizers, and keep allocations until exit:
# the distributed tests run in the release pass).
#   scripts/test-sanitizers.sh [--build-only]
set -euo pipefail
cd "$(dirname "$0")/.."
build_only=0
case "${1:-}" in
  "") ;;
  --build-only) build_only=1 ;;
  *) echo "test-sanitizers.sh: unknown option '$1' (the only one is --build-only)" >&2; exit 2 ;;
esac
# -g1 (line tables and function names: what the sanitizers' stack traces print) instead of -g: CI
# had grown to 41 minutes, and full debug information took 27% of this build's compile time
# (src/morph/job.cpp: 53 s against 39 s) and made the objects 2.4x larger to link. The suppressions
# (scripts/lsan.supp) name libraries, which need no debug information.
# The tests' own code is built without UBSan (tests/CMakeLists.txt): the whole build took 13.1
# minutes here against 15.5, its tests 425 s against 470. -O0 for everything but the core (tried)
# made the build 689 s but its tests 648 s.
# -O1 (AddressSanitizer's own advice) instead of -O2: CI reached 49 minutes, and UBSan's checks
# inlined through Eigen make -O2 slow to compile: tests/core/test_fast_paths.cpp 49 s against 90 s,
# test_space_map.cpp 34 s against 45 s. This whole build took 15.5 minutes here (2 cores), its tests
# 173 s (the "gl" pass) and 297 s.
cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCSRBF_SANITIZE=ON \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
  -DCSRBF_BUILD_PYTHON=OFF -DCSRBF_BUILD_BENCH=OFF -DCSRBF_BUILD_MPI=OFF > /dev/null
cmake --build build-asan --parallel "$(nproc)"
[ "$build_only" = 1 ] && exit 0
# intercept_strndup=0: libxkbcommon-x11 (under Qt) reads past a string with strndup; not ours.
asan=abort_on_error=1:strict_string_checks=1:detect_stack_use_after_return=1:intercept_strndup=0
export LSAN_OPTIONS=suppressions=$PWD/scripts/lsan.supp:print_suppressions=0
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
# No test depends on the caller's display (scripts/test.sh).
unset DISPLAY
export HWLOC_COMPONENTS=-gl
# Processes that render (label "gl") are checked for memory errors but not for leaks: Mesa's driver
# is unloaded at exit before LeakSanitizer can name what it allocated. Everything else is checked
# for leaks too. The "consumer" tests (OpenFOAM, Gmsh, VTK and meshio judging csrbf morph's
# outputs) are left out: test_morph runs the same readers and writers under the sanitizers; so is
# the hostile-case generator ("attack": 250 whole-program runs), whose cases the catalogues repeat.
status=0
ASAN_OPTIONS=$asan:detect_leaks=0 ctest --test-dir build-asan --output-on-failure --parallel "$(nproc)" \
  --timeout 300 -L gl || status=$?
# fast_unwind_on_malloc=0: whole allocation stacks, so that suppressions can name third-party callers
# (not in the "gl" pass: the slow unwinder deadlocks against Mesa's driver being loaded).
ASAN_OPTIONS=$asan:detect_leaks=1:fast_unwind_on_malloc=0 ctest --test-dir build-asan --output-on-failure --parallel "$(nproc)" \
  --timeout 300 -LE "gl|consumer|attack" || status=$?
exit $status
