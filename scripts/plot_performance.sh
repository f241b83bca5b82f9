#!/usr/bin/env bash
# Draws docs/performance.png (cost against M and against N) from `csrbf bench --scenario scale --json`
# with gnuplot (Debian package gnuplot-nox).
# Usage: scripts/plot_performance.sh [scale.jsonl] [out.png]
#   Without a file it runs the benchmark first (a few minutes): build/bin/csrbf bench -s scale --json.
set -euo pipefail
cd "$(dirname "$0")/.."
in=${1:-}
out=${2:-docs/performance.png}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
if [[ -z "$in" ]]; then
  in="$work/scale.jsonl"
  build/bin/csrbf bench --scenario scale --json > "$in"
fi
/usr/bin/python3 - "$in" "$work" <<'PY'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1]) if l.startswith("{")]
rows = [r for r in rows if r.get("scenario") == "scale"]
with open(sys.argv[2] + "/m.dat", "w") as f:
    f.write("# M eval_us eval_float_us eval_1thread_us playback_us memcpy_us\n")
    for r in sorted((r for r in rows if r["sweep"] == "M"), key=lambda r: r["vertices"]):
        f.write("%d %g %g %g %g %g\n" % (r["vertices"], r["eval_us"], r["eval_float_us"], r["eval_1thread_us"],
                                         r["playback_us"], r["memcpy_us"]))
with open(sys.argv[2] + "/n.dat", "w") as f:
    f.write("# N fit_us factorization_us eval_us\n")
    byn = {r["controls"]: r for r in rows if r["vertices"] == 1000000}
    for n in sorted(byn):
        r = byn[n]
        f.write("%d %g %g %g\n" % (n, r["fit_us"], r["factorization_us"], r["eval_us"]))
PY
tmp="$out.tmp.png"
gnuplot <<GP
set terminal pngcairo size 1200,480 font "sans,10"
set output "$tmp"
set multiplot layout 1,2 title "csrbf scale scenario: controls and vertices on the unit sphere, about 25 neighbours a control, C2 kernel"
set logscale xy
set grid
set key top left
set format x "10^{%L}"
set format y "10^{%L}"
set xlabel "vertices M (N = 10^4 controls)"
set ylabel "median time (microseconds)"
plot "$work/m.dat" using 1:2 with linespoints lw 2 title "full evaluation, double, 2 threads", \
     "" using 1:3 with linespoints lw 2 title "full evaluation, float, 2 threads", \
     "" using 1:4 with linespoints lw 2 title "full evaluation, double, 1 thread", \
     "" using 1:5 with linespoints lw 2 title "playback (kept displacements), float", \
     "" using 1:6 with linespoints dt 2 lw 2 title "memcpy of the same bytes"
set xlabel "controls N (M = 10^6 vertices)"
plot "$work/n.dat" using 1:2 with linespoints lw 2 title "fit (index, ordering, factorisation, solve)", \
     "" using 1:3 with linespoints lw 2 title "of which factorisation", \
     "" using 1:4 with linespoints lw 2 title "full evaluation of 10^6 vertices, 2 threads"
unset multiplot
GP
mv "$tmp" "$out"
echo "wrote $out"
