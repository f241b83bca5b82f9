#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (AddressSanitizer + UndefinedBehaviorSanitizer) and runs each
# for SECONDS (default 600), at most JOBS at once (default: the number of cores). Crashes, leaks and
# timeouts land in build-fuzz/findings/TARGET/; the corpora grown from fuzz/corpus/TARGET in
# build-fuzz/corpus/TARGET. Exit status: non-zero if any target found something.
#   bash scripts/fuzz.sh [SECONDS] [TARGET...]
# targets: controls deformation scene spacemap mesh_obj mesh_ply mesh_off mesh_xyz mesh_stl mesh_glb
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-600}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(controls deformation scene spacemap mesh_obj mesh_ply mesh_off mesh_xyz mesh_stl mesh_glb)
jobs=${JOBS:-$(nproc)}
command -v clang++ > /dev/null || { echo "fuzz: clang++ is needed (bash scripts/install-deps.sh)"; exit 2; }
CC=clang CXX=clang++ cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCSRBF_FUZZ=ON \
  -DCSRBF_BUILD_APPS=OFF -DCSRBF_BUILD_GUI=OFF -DCSRBF_BUILD_TESTS=OFF -DCSRBF_BUILD_BENCH=OFF \
  -DCSRBF_BUILD_PYTHON=OFF -DCSRBF_BUILD_RENDER=OFF -DCSRBF_BUILD_VTK=OFF -DCSRBF_BUILD_MORPH=OFF -DCSRBF_WITH_AVX512=ON > /dev/null
cmake --build build-fuzz --parallel "$(nproc)" --target $(printf 'fuzz_%s ' "${targets[@]}")
status=0
run() {
  local t=$1
  mkdir -p "build-fuzz/corpus/$t" "build-fuzz/findings/$t"
  cp -n fuzz/corpus/"$t"/* "build-fuzz/corpus/$t/" 2>/dev/null || true
  # -rss_limit_mb: a single input may not take more than 2 GiB; -timeout: nor more than 10 s.
  # allocator_may_return_null: a huge allocation fails with std::bad_alloc, as it does outside ASan
  # (csrbf reports it); leaks inside third-party libraries (assimp's own on malformed files) are suppressed as in the
  # sanitizer suite (scripts/lsan.supp).
  LSAN_OPTIONS=suppressions=$PWD/scripts/lsan.supp:print_suppressions=0 ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=1 "build-fuzz/bin/fuzz_$t" "build-fuzz/corpus/$t" -max_total_time="$seconds" \
    -timeout=10 -rss_limit_mb=2048 -max_len=65536 -print_final_stats=1 \
    -artifact_prefix="build-fuzz/findings/$t/" > "build-fuzz/fuzz_$t.log" 2>&1
}
pids=()
for t in "${targets[@]}"; do
  while [ "$(jobs -rp | wc -l)" -ge "$jobs" ]; do sleep 1; done
  run "$t" & pids+=("$!:$t")
done
for p in "${pids[@]}"; do
  pid=${p%%:*} t=${p#*:}
  if wait "$pid"; then r=ok; else r=FOUND; status=1; fi
  runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "build-fuzz/fuzz_$t.log" | grep -o '[0-9]*$' || echo '?')
  echo "fuzz_$t: $r, $runs inputs in ${seconds}s, corpus $(ls "build-fuzz/corpus/$t" | wc -l) files, log build-fuzz/fuzz_$t.log"
done
exit $status
