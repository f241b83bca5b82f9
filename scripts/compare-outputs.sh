#!/usr/bin/env bash
# Outputs of two builds of csrbf, byte for byte: `csrbf deform`, `export` and `morph` on the bundled
# examples, each run by both programs into folders of their own, then compared file by file. For a
# restructure that must not change behaviour (issue 50): build the commit before it beside this one.
#   bash scripts/compare-outputs.sh OLD_CSRBF NEW_CSRBF
set -euo pipefail
old=$1 new=$2
cd "$(dirname "$0")/.."
ex=examples
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
run() {  # run NAME ARGS... (with @OUT@ the output path's folder)
  local name=$1; shift
  for side in old new; do
    local bin=$old; [ "$side" = new ] && bin=$new
    mkdir -p "$tmp/$side"
    "$bin" "${@//@OUT@/$tmp/$side}" > /dev/null 2> "$tmp/$side/$name.stderr" || { cat "$tmp/$side/$name.stderr"; echo "$side: $name failed"; exit 1; }
  done
}
run fish.obj deform --mesh $ex/fish.obj --controls $ex/fish.controls --radius 0.3 -o @OUT@/fish.obj
run bunny.ply deform --mesh $ex/bunny.obj --controls $ex/bunny.controls --radius 2.5 --kernel c4 --polynomial linear \
  --phase 0.5 -o @OUT@/bunny.ply
run face.obj deform --mesh $ex/face.obj --controls $ex/face.controls --radius 0.2 --solver cg -o @OUT@/face.obj
for s in fish face ball; do
  run $s.glb export $ex/$s.scene.json -o @OUT@/$s.glb
  run $s.gltf export $ex/$s.scene.json -o @OUT@/$s.gltf
  run $s-compact.glb export $ex/$s.scene.json --compact -o @OUT@/$s-compact.glb
  run $s-only.glb export $ex/$s.scene.json --compact=only -o @OUT@/$s-only.glb
  run $s-meshopt.glb export $ex/$s.scene.json --meshopt --quantize -o @OUT@/$s-meshopt.glb
done
run pitched morph $ex/airfoil/case -o @OUT@/pitched --motion $ex/airfoil/motion.json
run pitched.msh morph $ex/airfoil/airfoil.msh -o @OUT@/pitched.msh --motion $ex/airfoil/motion.json
files=0
while IFS= read -r -d '' f; do
  rel=${f#"$tmp/old/"}
  case "$rel" in *.stderr) continue ;; esac
  cmp -s "$f" "$tmp/new/$rel" || { echo "compare-outputs: $rel differs"; exit 1; }
  files=$((files + 1))
done < <(find "$tmp/old" -type f -print0)
[ "$(find "$tmp/new" -type f ! -name '*.stderr' | wc -l)" = "$files" ] || { echo "compare-outputs: the new build wrote other files"; exit 1; }
echo "compare-outputs: $files files byte for byte the same ($old against $new)"
