#!/usr/bin/env bash
# An engine's glb player links csrbf::gltf (and csrbf::files) only: csrbf-play-glb loads no VTK, X11,
# assimp, MPI, Qt or GL library (issue 50: `ldd build/bin/csrbf-play-glb`), and still plays the fish
# that `csrbf export --compact` wrote, its extension's vertices equal to its morph targets'.
#   test_gltf_links.sh PLAY_GLB CSRBF SOURCE_DIR
set -euo pipefail
play=$1 cli=$2 src=$3
if ldd "$play" | grep -Ei 'libvtk|libX11|libassimp|libmpi|libQt|libGL'; then
  echo "csrbf-play-glb loads the libraries above"; exit 1
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$cli" export "$src/examples/fish.scene.json" --compact -o "$tmp/fish.glb" > /dev/null
out=$("$play" "$tmp/fish.glb" --fps 10)
echo "$out"
grep -q 'fish' <<< "$out" || { echo "csrbf-play-glb did not play the fish"; exit 1; }
echo "csrbf-play-glb: $(ldd "$play" | wc -l) libraries, none of VTK, X11, assimp, MPI, Qt or GL"
