#!/usr/bin/env python3
"""csrbf morph against OpenFOAM's own mesh motion (moveMesh with dynamicMotionSolverFvMesh and
displacementLaplacian, diffusivity quadratic inverseDistance on the moving wall: what an OpenFOAM
user picks, solved to convergence: PCG with DIC to 1e-30, its iterations printed and its result
checked against 1000 iterations or more), the same boundary motion in the same run, one JSON line a case and tool: wall time
end to end (reading and writing included), peak memory (the child's maximum resident set, by wait4), and
checkMesh's maximum non-orthogonality and skewness of the result. Medians of --repeat runs.

    /usr/bin/python3 bench/morph_openfoam.py --csrbf build/bin/csrbf [--case airfoil2d|pitzdaily|windaroundbuildings]
        [--scale K] [--repeat 3] [--format ascii|binary] [--greedy TOL] [--mesh-cache DIR]

Cases: airfoil2d, the tutorial's airFoil2D (21812 points) with its walls pitched by 3 degrees;
pitzdaily, the tutorial's blockMesh case with every block's cell counts multiplied by K in x and y
(K = 20: about 1e7 points), a 1 mm bump raised on its lower wall (ASCII: the bump is computed
from the ASCII points, and binary cases are converted after); windaroundbuildings, the tutorial's
snappyHexMesh mesh (about 219 000 points) with every building moved 0.5 m downwind, its ground and
symmetry planes slipping.
"""
import argparse
import json
import math
import os
import re
import shutil
import statistics
import subprocess
import time
import sys
import tempfile

TUTORIALS = "/usr/share/doc/openfoam-examples/examples/incompressible/simpleFoam"
ENV = dict(os.environ, WM_PROJECT_DIR="/usr/share/openfoam", OMPI_ALLOW_RUN_AS_ROOT="1",
           OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")


def sh(args, cwd=None):
    r = subprocess.run(args, cwd=cwd, env=ENV, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit("failed: %s\n%s%s" % (" ".join(args), r.stdout[-3000:], r.stderr[-3000:]))
    return r.stdout + r.stderr


def timed(args, cwd=None):
    """(wall seconds, peak resident MiB, standard output) of a child: the wall clock around its start and
    wait (GNU time's %e has 10 ms steps, a quarter of a 40 ms morph), its own peak by wait4."""
    import tempfile as _t
    with _t.TemporaryFile() as out, _t.TemporaryFile() as err:
        start = time.perf_counter()
        p = subprocess.Popen(args, cwd=cwd, env=ENV, stdout=out, stderr=err)
        _, status, usage = os.wait4(p.pid, 0)
        seconds = time.perf_counter() - start
        p.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        stdout, stderr = out.read().decode(errors="replace"), err.read().decode(errors="replace")
    if p.returncode != 0:
        sys.exit("failed: %s\n%s%s" % (" ".join(args), stdout[-3000:], stderr[-3000:]))
    return round(seconds, 4), usage.ru_maxrss / 1024.0, stdout


def check_mesh(case, time=None):
    out = sh(["checkMesh"] + (["-time", time] if time else []), cwd=case)
    non_orth = re.search(r"Mesh non-orthogonality Max: (\S+) average: (\S+)", out)
    skew = re.search(r"Max skewness = ([-+.0-9eE]+)", out)
    failed = re.findall(r"\*\*\*([^\n]*)", out)
    return {"max_non_orthogonality": float(non_orth.group(1)), "mean_non_orthogonality": float(non_orth.group(2)), "failed": failed,
            "max_skewness": float(skew.group(1)), "mesh_ok": "Mesh OK." in out,
            "negative_volumes": "negative volume" in out}


def set_format(case, fmt):
    path = os.path.join(case, "system", "controlDict")
    with open(path) as f:
        text = f.read()
    text = re.sub(r"writeFormat\s+\w+;", "writeFormat %s;" % fmt, text)
    text = re.sub(r"writePrecision\s+\d+;", "writePrecision 12;", text)
    with open(path, "w") as f:
        f.write(text)


def prepare(case, work, scale, fmt, cache=None):
    """The case, its mesh, and its motion as (csrbf motion, pointDisplacement boundary entries)."""
    if case == "airfoil2d":
        src = os.path.join(work, "airFoil2D")
        shutil.copytree(os.path.join(TUTORIALS, "airFoil2D"), src)
        set_format(src, fmt)
        if fmt == "binary":
            sh(["foamFormatConvert", "-constant"], cwd=src)
        degrees, origin = -3.0, [-8.75, 0, 0]
        motion = {"radius": 20.0, "patches": {
            "walls": {"rotate": {"axis": [0, 0, 1], "degrees": degrees, "origin": origin}},
            "inlet": "fixed", "outlet": "fixed"}}
        point_bcs = {
            "walls": "type angularOscillatingDisplacement; axis (0 0 1); origin (%g %g %g); angle0 %.17g; "
                     "amplitude 0; omega 0; value uniform (0 0 0);" % (*origin, math.radians(degrees)),
            "inlet": "type fixedValue; value uniform (0 0 0);",
            "outlet": "type fixedValue; value uniform (0 0 0);",
            "frontAndBack": "type empty;"}
        return src, motion, point_bcs, "walls"
    if case == "windaroundbuildings":
        # The tutorial's mesh (surfaceFeatureExtract, blockMesh, snappyHexMesh: about 219 000 points,
        # polyhedra), kept in --mesh-cache between runs; every building moved 0.5 m downwind. Its
        # ground (planar, unlisted) and the symmetry planes slip in csrbf as in the Laplacian.
        src = os.path.join(work, "windAroundBuildings")
        cached = os.path.join(cache, "windAroundBuildings-" + fmt) if cache else None
        if cached and os.path.isdir(cached):
            shutil.copytree(cached, src)
        else:
            shutil.copytree(os.path.join(TUTORIALS, "windAroundBuildings"), src)
            set_format(src, fmt)
            for step in (["surfaceFeatureExtract"], ["blockMesh"], ["snappyHexMesh", "-overwrite"]):
                sh(step, cwd=src)
            if cached:
                shutil.copytree(src, cached)
        # R = 40 (80 x the displacement): the cells nearest the converged Laplacian's (47.9 degrees of
        # non-orthogonality against its 47.7; auto's R = 10 gives 48.5), which two levels (--levels,
        # auto here) fit in a fraction of a second where one level takes 21 s.
        shift = (0.5, 0.0, 0.0)
        motion = {"radius": 40.0,
                  "patches": {"buildings": {"translate": list(shift)}, "inlet": "fixed", "outlet": "fixed"}}
        point_bcs = {"buildings": "type fixedValue; value uniform (%g %g %g);" % shift,
                     "inlet": "type fixedValue; value uniform (0 0 0);",
                     "outlet": "type fixedValue; value uniform (0 0 0);",
                     "ground": "type slip;",
                     "frontAndBack": "type symmetry;"}
        return src, motion, point_bcs, "buildings"
    src = os.path.join(work, "pitzDaily")
    shutil.copytree(os.path.join(TUTORIALS, "pitzDaily"), src)
    path = os.path.join(src, "system", "blockMeshDict")
    with open(path) as f:
        text = f.read()
    text = re.sub(r"\((\d+) (\d+) 1\)", lambda m: "(%d %d 1)" % (int(m.group(1)) * scale, int(m.group(2)) * scale), text)
    with open(path, "w") as f:
        f.write(text)
    sh(["blockMesh"], cwd=src)
    # A smooth bump on the lower wall downstream of the step (shape optimisation's kind of motion):
    # dy = A sin^2(pi (x - x0) / L) for x0 < x < x0 + L, given point by point to both tools (OpenFOAM
    # takes the patch's values in its point order: the order points first appear in its faces).
    poly = os.path.join(src, "constant", "polyMesh")
    points, faces, start, count = read_patch(poly, "lowerWall")
    x0, length, amplitude = 0.05, 0.1, 0.001
    order, seen = [], set()
    for f in faces[start:start + count]:
        for v in f:
            if v not in seen:
                seen.add(v)
                order.append(v)
    dy = [amplitude * math.sin(math.pi * (points[v][0] - x0) / length) ** 2 if x0 < points[v][0] < x0 + length else 0.0
          for v in order]
    with open(os.path.join(work, "bump.txt"), "w") as f:
        for v, d in zip(order, dy):
            f.write("%d 0 %.17g 0\n" % (v, d))
    motion = {"radius": 0.02, "patches": {"lowerWall": {"displacements": "bump.txt"}, "upperWall": "fixed",
                                          "inlet": "fixed", "outlet": "fixed"}}
    values = " ".join("(0 %.17g 0)" % d for d in dy)
    point_bcs = {"lowerWall": "type fixedValue; value nonuniform List<vector> %d(%s);" % (len(dy), values),
                 "upperWall": "type fixedValue; value uniform (0 0 0);",
                 "inlet": "type fixedValue; value uniform (0 0 0);",
                 "outlet": "type fixedValue; value uniform (0 0 0);",
                 "frontAndBack": "type empty;"}
    if fmt == "binary":
        set_format(src, fmt)
        sh(["foamFormatConvert", "-constant"], cwd=src)
    return src, motion, point_bcs, "lowerWall"


def read_patch(poly, name):
    """(points, faces, startFace, nFaces) of an ASCII polyMesh's patch."""
    def body(path):
        with open(path) as f:
            text = f.read()
        return text[text.index("}") + 1:]
    pts = [tuple(map(float, m)) for m in re.findall(r"\(([-\d.e+]+) ([-\d.e+]+) ([-\d.e+]+)\)", body(os.path.join(poly, "points")))]
    faces = [list(map(int, f.split())) for f in re.findall(r"\d+\(([\d ]+)\)", body(os.path.join(poly, "faces")))]
    b = body(os.path.join(poly, "boundary"))
    m = re.search(name + r"\s*\{[^}]*?nFaces\s+(\d+);\s*startFace\s+(\d+);", b, re.S)
    return pts, faces, int(m.group(2)), int(m.group(1))


# The Laplacian solved as its experts solve one motion step: to convergence. GAMG at tolerance 1e-8
# and relTol 0 stopped after one V-cycle (its normalised residual is tiny at once) 20-35 % away from
# the converged displacement. PCG with DIC to 1e-30 runs to round-off (about 150 iterations on
# airFoil2D); CHECK forces 1000 to show that nothing changes after.
CONVERGED = "solver PCG; preconditioner DIC; tolerance 1e-30; relTol 0; maxIter 20000;"
CHECK = "solver PCG; preconditioner DIC; tolerance 1e-30; relTol 0; minIter 1000; maxIter 20000;"


def laplacian_case(src, dst, point_bcs, wall, solver=CONVERGED):
    """src set up for one step of moveMesh with displacementLaplacian."""
    shutil.copytree(src, dst)
    for d in os.listdir(dst):  # the tutorial's fields are not needed; 0/pointDisplacement is
        if re.fullmatch(r"[0-9.]+", d):
            shutil.rmtree(os.path.join(dst, d))
    os.makedirs(os.path.join(dst, "0"))
    header = "FoamFile { version 2.0; format ascii; class %s; object %s; }\n"
    with open(os.path.join(dst, "constant", "dynamicMeshDict"), "w") as f:
        f.write(header % ("dictionary", "dynamicMeshDict"))
        f.write("dynamicFvMesh dynamicMotionSolverFvMesh;\nmotionSolverLibs (fvMotionSolvers);\n"
                "motionSolver displacementLaplacian;\ndisplacementLaplacianCoeffs { diffusivity quadratic "
                "inverseDistance 1(%s); }\ndiffusivity quadratic inverseDistance 1(%s);\n" % (wall, wall))
    with open(os.path.join(dst, "0", "pointDisplacement"), "w") as f:
        f.write(header % ("pointVectorField", "pointDisplacement"))
        f.write("dimensions [0 1 0 0 0 0 0];\ninternalField uniform (0 0 0);\nboundaryField\n{\n")
        for name, bc in point_bcs.items():
            f.write("    %s { %s }\n" % (name, bc))
        f.write("}\n")
    with open(os.path.join(dst, "system", "fvSolution"), "w") as f:
        f.write(header % ("dictionary", "fvSolution"))
        f.write('solvers { "cellDisplacement.*" { %s } }\n' % solver + "PIMPLE { nOuterCorrectors 1; }\n")
    path = os.path.join(dst, "system", "controlDict")
    with open(path) as f:
        text = f.read()
    for key, value in (("startTime", "0"), ("endTime", "1"), ("deltaT", "1"), ("writeInterval", "1"),
                       ("writeControl", "timeStep"), ("startFrom", "startTime")):
        text = re.sub(r"\b%s\s+[^;]+;" % key, "%s %s;" % (key, value), text)
    text = re.sub(r"functions\s*\{.*", "", text, flags=re.S)
    with open(path, "w") as f:
        f.write(text)
    with open(os.path.join(dst, "system", "fvSchemes"), "a") as f:
        f.write("\n")


def moved_points(case, time="1"):
    """The points moveMesh wrote for a time (ASCII, gzipped or not)."""
    import gzip
    poly = os.path.join(case, time, "polyMesh") if time != "constant" else os.path.join(case, "constant", "polyMesh")
    path = os.path.join(poly, "points")
    text = (gzip.open(path + ".gz", "rt") if os.path.exists(path + ".gz") else open(path)).read()
    body = text[text.index("}") + 1:]
    return [tuple(map(float, m)) for m in re.findall(r"\(([-\d.e+]+) ([-\d.e+]+) ([-\d.e+]+)\)", body)]


def iterations(log):
    """PCG's iterations per component of the displacement: {component: n}; a solve that reached a
    residual of exactly 0 (OpenFOAM then stops and prints "solution singularity", without its
    count, even under minIter) is reported as that."""
    found = {m.group(1): int(m.group(2)) for m in
             re.finditer(r"Solving for cellDisplacement(\w), Initial residual = \S+, Final residual = \S+, "
                         r"No Iterations (\d+)", log)}
    for m in re.finditer(r"Solving for cellDisplacement(\w):  solution singularity", log):
        found[m.group(1)] = "stopped at a residual of exactly 0 (OpenFOAM: solution singularity)"
    return found


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--csrbf", required=True)
    p.add_argument("--case", choices=("airfoil2d", "pitzdaily", "windaroundbuildings"), default="airfoil2d")
    p.add_argument("--mesh-cache", help="windaroundbuildings: keep the snappyHexMesh mesh in this folder")
    p.add_argument("--scale", type=int, default=1)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--format", choices=("ascii", "binary"), default="ascii")
    p.add_argument("--greedy", type=float, default=0.0, help="csrbf morph --greedy TOL")
    p.add_argument("--skip-openfoam", action="store_true")
    a = p.parse_args()
    work = tempfile.mkdtemp(prefix="csrbf-bench-morph-")
    try:
        src, motion, point_bcs, wall = prepare(a.case, work, a.scale, a.format, a.mesh_cache)
        with open(os.path.join(work, "motion.json"), "w") as f:
            json.dump(motion, f)
        rows = []
        times, mems = [], []
        for k in range(a.repeat):
            out = os.path.join(work, "csrbf-%d" % k)
            t, m, stdout = timed([a.csrbf, "morph", src, "-o", out, "--motion", os.path.join(work, "motion.json"),
                                  "--json"] + (["--greedy", repr(a.greedy)] if a.greedy else []))
            times.append(t)
            mems.append(m)
            report = json.loads(stdout)
            if k + 1 < a.repeat:
                shutil.rmtree(out)
        points = report["points"]
        q = check_mesh(out)
        rows.append({"case": a.case, "scale": a.scale, "format": a.format, "points": points, "cells": report["cells"],
                     "tool": "csrbf", "seconds": statistics.median(times), "seconds_all": times,
                     "peak_mib": statistics.median(mems), "controls": report["controls"], "greedy": a.greedy,
                     "ms": report["ms"], **q})
        if not a.skip_openfoam:
            times, mems = [], []
            for k in range(a.repeat):
                case = os.path.join(work, "laplacian-%d" % k)
                laplacian_case(src, case, point_bcs, wall)
                t, m, log = timed(["moveMesh"], cwd=case)
                times.append(t)
                mems.append(m)
            q = check_mesh(case, "1")
            # The check: 1000 iterations or more move no point further than round-off.
            check = os.path.join(work, "laplacian-check")
            laplacian_case(src, check, point_bcs, wall, CHECK)
            _, _, check_log = timed(["moveMesh"], cwd=check)
            got, longer = moved_points(case), moved_points(check)
            base = moved_points(src, os.path.join("constant"))
            gap = max(abs(x - y) for p, r in zip(got, longer) for x, y in zip(p, r))
            moved = max(abs(x - y) for p, r in zip(longer, base) for x, y in zip(p, r))
            rows.append({"case": a.case, "scale": a.scale, "format": a.format, "points": points,
                         "cells": report["cells"], "tool": "displacementLaplacian (PCG/DIC to 1e-30)",
                         "seconds": statistics.median(times), "seconds_all": times,
                         "peak_mib": statistics.median(mems), "iterations": iterations(log),
                         "check_iterations": iterations(check_log),
                         "largest_difference_to_check": gap / moved, **q})
            rows.append({"case": a.case, "scale": a.scale, "points": points,
                         "speedup": rows[1]["seconds"] / rows[0]["seconds"]})
        for r in rows:
            print(json.dumps(r), flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
