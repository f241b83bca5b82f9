#!/usr/bin/env bash
# The C API's GPU layout (csrbf_gpu_fill) against csrbf_deformation.js, texel for texel: the fish
# (92 controls, R = 0.3) fitted through csrbf.h and laid out at a weight, against the same controls
# exported by `csrbf export --compact` and loaded in node by three's GLTFLoader with the module's
# plugin, as a page loads it (gpu_layout.mjs). Three fits: C2 without a polynomial (the default), C4
# with a linear one, and C0 with a constant one at weight 0 (the shader skips it).
#   test_gpu_layout.sh C_CONSUMER CSRBF SOURCE_DIR WEB_DIR NODE_MODULES
set -euo pipefail
consumer=$1 cli=$2 src=$3 web=$4 modules=$5
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# The module beside a node_modules that holds three, as a bundler or a page's import map finds it.
cp "$web/csrbf_deformation.js" "$src/tests/capi/gpu_layout.mjs" "$tmp/"
ln -s "$modules" "$tmp/node_modules"
for c in "c2 none 2 0 0.7" "c4 linear 4 2 0.35" "c0 constant 0 1 0"; do
  read -r kernel polynomial k p weight <<< "$c"
  cat > "$tmp/$kernel.scene.json" <<JSON
{"format": "csrbf-scene", "version": 1, "duration": 1.0, "fps": 10,
 "objects": [{"name": "fish", "mesh": "$src/examples/fish.obj",
   "parts": [{"name": "body", "deformations": [{"name": "swim", "controls": "$src/examples/fish.controls",
     "radius": 0.3, "kernel": "$kernel", "polynomial": "$polynomial",
     "phase": {"keys": [{"time": 0, "phase": 0}, {"time": 1, "phase": 1}]}}]}]}]}
JSON
  "$cli" export "$tmp/$kernel.scene.json" -o "$tmp/$kernel.glb" --compact > /dev/null
  (cd "$tmp" && node gpu_layout.mjs "$kernel.glb" "$weight" "$tmp/js-$kernel")
  "$consumer" "$src/examples/fish.obj" "$src/examples/fish.controls" 0.3 "$tmp/c-$kernel" "$weight" "$k" "$p" \
    > /dev/null
  for texture in sources coefficients deformations cells list groups; do
    if ! cmp -s "$tmp/c-$kernel.$texture.bin" "$tmp/js-$kernel.$texture.bin"; then
      echo "$kernel $polynomial at weight $weight: the C API's $texture differ from csrbf_deformation.js's:" >&2
      cmp "$tmp/c-$kernel.$texture.bin" "$tmp/js-$kernel.$texture.bin" >&2 || true
      exit 1
    fi
  done
  echo "$kernel $polynomial at weight $weight: the six textures are equal, byte for byte"
done
