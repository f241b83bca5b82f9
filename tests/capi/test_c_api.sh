#!/usr/bin/env bash
# The C API (csrbf.h) against the program: the C consumer (deform_fish.c, built with -std=c11 -Wall
# -Wextra -Werror -pedantic) deforms the paper's fish (92 controls, R = 0.3) and every vertex equals
# `csrbf deform`'s to 1e-12. Then the same file compiled by hand with the system's C compiler, as a
# user outside CMake would: `cc -std=c11 -Werror` against the header alone.
#   test_c_api.sh C_CONSUMER CSRBF SOURCE_DIR
set -euo pipefail
consumer=$1 cli=$2 src=$3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$consumer" "$src/examples/fish.obj" "$src/examples/fish.controls" 0.3 > "$tmp/c.obj"
"$cli" deform --mesh "$src/examples/fish.obj" --controls "$src/examples/fish.controls" --radius 0.3 \
  -o "$tmp/cli.obj" > /dev/null
/usr/bin/python3 - "$tmp/c.obj" "$tmp/cli.obj" <<'PY'
import sys
def vertices(path):
    return [tuple(map(float, l.split()[1:4])) for l in open(path) if l.startswith("v ")]
c, cli = vertices(sys.argv[1]), vertices(sys.argv[2])
assert len(c) == len(cli) == 977, (len(c), len(cli))
worst = max(abs(a - b) for p, q in zip(c, cli) for a, b in zip(p, q))
print(f"C API against csrbf deform: {len(c)} vertices, largest difference {worst:.3g}")
assert worst <= 1e-12, worst
PY
cc -std=c11 -Wall -Wextra -Werror -pedantic -I "$src/include" -c "$src/tests/capi/deform_fish.c" -o "$tmp/deform_fish.o"
echo "cc -std=c11 -Werror: compiles against csrbf.h"
