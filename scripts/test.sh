#!/usr/bin/env bash
# Installs what is needed, builds everything and runs every test (the README's second command).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build --parallel "$(nproc)"
# No test may depend on the caller's display: each GUI test starts an Xvfb of its own
# (tests/with-xvfb.sh), and nothing else may touch one (Open MPI's hwloc probes X displays).
env -u DISPLAY HWLOC_COMPONENTS=-gl ctest --test-dir build --output-on-failure --parallel "$(nproc)"
