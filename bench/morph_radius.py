#!/usr/bin/env python3
"""What the radius of `csrbf morph` costs and buys, on OpenFOAM's tutorials: `--radius auto` and
multiples of the R it picks, each run once, one markdown row a run: R, the controls fitted, the
neighbours predicted per control and per point, the quality after (largest non-orthogonality,
smallest cell volume ratio after / before, smallest cell determinant: the same figures as
checkMesh), the fit's and the evaluation's times beside their predictions, and the peak memory
(GNU time's maximum resident set) beside the fit's predicted memory.

    /usr/bin/python3 bench/morph_radius.py --csrbf build/bin/csrbf [--case airfoil2d|pitzdaily] [--scale K]

The cases and their motions are bench/morph_openfoam.py's, without their radius (auto).
"""
import argparse
import json
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from morph_openfoam import prepare, timed  # noqa: E402


def row(csrbf, case, motion_path, radius, out):
    args = [csrbf, "morph", case, "-o", out, "--motion", motion_path, "--json", "--radius", radius, "--force"]
    wall, peak, stdout = timed(args)
    r = json.loads(stdout)
    q = r["quality"]["after"]["polyhedra"]
    p = r["predicted"]
    return ("| %.4g | %d | %.0f / %.0f | %.2f | %.4f | %.4g | %.0f / %.0f | %.0f / %.0f | %.0f / %.0f | %.2f |"
            % (r["radius"], r["controls"], p["neighbours_per_control"], p["neighbours_per_point"],
               q["max_non_orthogonality"], q["min_volume_ratio"], q["min_determinant"], r["ms"]["fit"],
               p["seconds_fit"] * 1e3, r["ms"]["evaluate"], p["seconds_evaluate"] * 1e3, peak,
               p["bytes"] / 2**20, wall)), r


def main():
    a = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    a.add_argument("--csrbf", required=True)
    a.add_argument("--case", choices=("airfoil2d", "pitzdaily"), default="airfoil2d")
    a.add_argument("--scale", type=int, default=1)
    args = a.parse_args()
    with tempfile.TemporaryDirectory() as work:
        case, motion, _, _ = prepare(args.case, work, args.scale, "ascii")
        motion.pop("radius")
        path = os.path.join(work, "motion.json")
        with open(path, "w") as f:
            json.dump(motion, f)
        print("%s (scale %d)\n" % (args.case, args.scale))
        print("| R | controls | neighbours per control / point (predicted) | max non-orth (deg) | "
              "min volume after/before | min determinant | fit ms / predicted | evaluate ms / predicted | "
              "peak MiB / fit predicted | wall s |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        line, auto = row(args.csrbf, case, path, "auto", os.path.join(work, "auto"))
        print(line + " auto: " + auto["radius_why"])
        for k, factor in enumerate((0.25, 0.5, 2.0, 4.0)):
            line, _ = row(args.csrbf, case, path, repr(factor * auto["radius"]), os.path.join(work, "r%d" % k))
            print(line)


if __name__ == "__main__":
    main()
