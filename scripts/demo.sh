#!/usr/bin/env bash
# Installs what is needed, builds, deforms the bundled fish, prints the solver's statistics and
# renders the fish's animation to fish.mp4 (the README's first command).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build --parallel "$(nproc)" --target csrbf
build/bin/csrbf deform --mesh examples/fish.obj --controls examples/fish.controls --radius 0.3 -o fish-deformed.obj
build/bin/csrbf info --controls examples/fish.controls --radius 0.3
build/bin/csrbf animate examples/fish.scene.json -o fish.mp4
