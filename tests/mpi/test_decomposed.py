"""mpirun csrbf morph|deform judged against the serial program and by OpenFOAM's own tools and VTK:
decomposePar (simple and hierarchical; Debian's OpenFOAM has no scotch), mpirun -np K csrbf morph,
reconstructParMesh, checkMesh; .pvtu pieces, a rank each; the distributed points equal the serial
morph's to 1e-10 of the
largest displacement; a single mesh morphed and deformed from rank 0; a failing input on one rank
only; the wrong number of ranks.

    CSRBF_CLI=build/bin/csrbf CSRBF_SOURCE_DIR=. /usr/bin/python3 -m unittest -v test_decomposed
"""
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import unittest

import numpy as np

CLI = os.environ.get("CSRBF_CLI", "csrbf")
SOURCE = os.environ.get("CSRBF_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
TUTORIALS = "/usr/share/doc/openfoam-examples/examples/incompressible/simpleFoam"
ENV = dict(os.environ, WM_PROJECT_DIR="/usr/share/openfoam", OMPI_ALLOW_RUN_AS_ROOT="1",
           OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMPI_MCA_rmaps_base_oversubscribe="1")
MPIRUN = ["mpirun", "--oversubscribe", "-np"]


def run(args, cwd=None):
    return subprocess.run(args, cwd=cwd, env=ENV, capture_output=True, text=True, timeout=600)


def foam_list(path):
    """The body of an ASCII OpenFOAM list file: (count, text after its '(')."""
    with open(path) as f:
        t = f.read()
    t = re.sub(r"/\*.*?\*/", "", t, flags=re.S)
    t = re.sub(r"//[^\n]*", "", t)
    body = t[t.index("}", t.index("FoamFile")) + 1:]
    m = re.search(r"(\d+)\s*\(", body)
    return int(m.group(1)), body[m.end():]


def points(poly):
    n, body = foam_list(os.path.join(poly, "points"))
    return np.array([[float(x) for x in s.split()] for s in re.findall(r"\(([^()]*)\)", body)[:n]])


def labels(path):
    n, body = foam_list(path)
    return np.array([int(x) for x in body.split(")")[0].split()[:n]])


def gathered(case, count):
    """The processors' points placed by pointProcAddressing: the whole mesh's numbering."""
    parts = []
    for k in range(count):
        poly = os.path.join(case, "processor%d" % k, "constant", "polyMesh")
        parts.append((labels(os.path.join(poly, "pointProcAddressing")), points(poly)))
    out = np.full((max(a.max() for a, _ in parts) + 1, 3), np.nan)
    for a, p in parts:
        out[a] = p
    return out


def decompose(case, count, method, n):
    with open(os.path.join(case, "system", "decomposeParDict"), "w") as f:
        f.write("FoamFile { version 2.0; format ascii; class dictionary; object decomposeParDict; }\n"
                "numberOfSubdomains %d;\nmethod %s;\n"
                "simpleCoeffs { n (%s); }\nhierarchicalCoeffs { n (%s); order xyz; }\n"
                % (count, method, n, n))
    r = run(["decomposePar", "-force"], cwd=case)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]


def full_precision(case):
    """decomposePar writes the processors' points with the case's writePrecision: 17 digits keep
    them exact, so that the serial and distributed morphs start from the same points."""
    cd = os.path.join(case, "system", "controlDict")
    with open(cd) as f:
        t = f.read()
    t = re.sub(r"writePrecision\s+\d+;", "writePrecision 17;", t)
    if "writePrecision" not in t:
        t += "\nwritePrecision 17;\n"
    with open(cd, "w") as f:
        f.write(t)


class Decomposed(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="csrbf-mpi-")

    def tearDown(self):
        shutil.rmtree(self.tmp, ignore_errors=True)

    def path(self, *p):
        return os.path.join(self.tmp, *p)

    def airfoil(self, name="case"):
        case = self.path(name)
        shutil.copytree(os.path.join(SOURCE, "examples", "airfoil", "case"), case)
        full_precision(case)
        with open(self.path("motion.json"), "w") as f:
            json.dump({"radius": 1.5, "kernel": "c2", "polynomial": "none",
                       "patches": {"airfoil": {"rotate": {"axis": [0, 0, 1], "degrees": -5, "origin": [0.25, 0, 0]}},
                                   "farfield": "fixed"}}, f)
        return case

    def check_mesh(self, case):
        r = run(["checkMesh"], cwd=case)
        self.assertIn("Mesh OK.", r.stdout, r.stdout[-3000:])

    def test_a_time_folder_of_every_part_is_read_and_written(self):
        # Issue 31, point 6, under mpirun: each part's time folder (here without a mesh of its own,
        # so constant's is read, as OpenFOAM does) gets its moved points; constant/ stays, and the
        # result equals the serial morph of the same time.
        plain = self.airfoil("plain-time")
        case = self.path("case-time")
        shutil.copytree(plain, case)
        decompose(case, 2, "simple", "2 1 1")
        def raw(path):
            with open(path, "rb") as f:
                return f.read()

        before = [raw(os.path.join(case, "processor%d/constant/polyMesh/points" % k)) for k in range(2)]
        for k in range(2):
            os.mkdir(os.path.join(case, "processor%d" % k, "0.5"))
        os.mkdir(os.path.join(plain, "0.5"))
        r = run(MPIRUN + ["2", CLI, "morph", case, "--in-place", "-time", "0.5", "--motion", self.path("motion.json"),
                          "--json"])
        self.assertEqual(r.returncode, 0, r.stdout[-2000:] + r.stderr[-3000:])
        self.assertEqual(json.loads(r.stdout)["time"], "0.5")
        for k in range(2):
            poly = os.path.join(case, "processor%d" % k)
            self.assertEqual(raw(os.path.join(poly, "constant/polyMesh/points")), before[k])
            self.assertTrue(os.path.exists(os.path.join(poly, "0.5/polyMesh/points")))
        r = run([CLI, "morph", plain, "--in-place", "-time", "0.5", "--motion", self.path("motion.json")])
        self.assertEqual(r.returncode, 0, r.stderr)
        want = points(os.path.join(plain, "0.5", "polyMesh"))
        got = np.full(want.shape, np.nan)
        for k in range(2):
            part = os.path.join(case, "processor%d" % k)
            got[labels(os.path.join(part, "constant/polyMesh/pointProcAddressing"))] = points(
                os.path.join(part, "0.5", "polyMesh"))
        self.assertLess(np.abs(got - want).max(), 1e-10)
        self.assertGreater(np.abs(want - points(os.path.join(plain, "constant", "polyMesh"))).max(), 0.01)
        for k in range(2):
            r = run(["checkMesh", "-time", "0.5"], cwd=os.path.join(case, "processor%d" % k))
            self.assertIn("Mesh OK.", r.stdout, r.stdout[-3000:])

    def serial(self, case, out, *extra):
        r = run([CLI, "morph", case, "-o", out, "--motion", self.path("motion.json"), "--json", *extra])
        self.assertEqual(r.returncode, 0, r.stderr)
        self.serial_report = json.loads(r.stdout)
        return points(os.path.join(out, "constant", "polyMesh"))

    def test_decomposed_cases_equal_the_serial_morph_and_pass_checkmesh(self):
        plain = self.airfoil("plain")
        for count, method, n in ((2, "simple", "2 1 1"), (3, "hierarchical", "3 1 1"), (4, "hierarchical", "2 2 1")):
            # Each kernel at a radius where its system is well conditioned: the two solves (the serial
            # envelope or CHOLMOD, MUMPS here) then agree to ~1e-12; at a condition number of 1e8 they
            # differ by ~1e-8 (docs/DISTRIBUTED.md).
            for kernel, poly, radius in (("c0", "none", 1.5), ("c2", "constant", 1.5), ("c4", "none", 0.4),
                                         ("c6", "constant", 0.25)):
                with self.subTest(ranks=count, method=method, kernel=kernel, polynomial=poly):
                    case = self.path("case-%d-%s" % (count, kernel))
                    shutil.rmtree(case, ignore_errors=True)
                    shutil.copytree(plain, case)
                    decompose(case, count, method, n)
                    inputs = [open(os.path.join(case, "processor%d/constant/polyMesh/points" % k), "rb").read()
                              for k in range(count)]
                    extra = ["--kernel", kernel, "--polynomial", poly, "--radius", str(radius)]
                    want = self.serial(plain, self.path("serial-%d-%s" % (count, kernel)), *extra)
                    out = self.path("out-%d-%s" % (count, kernel))
                    r = run(MPIRUN + [str(count), CLI, "morph", case, "-o", out, "--motion", self.path("motion.json"),
                                      "--json", *extra])
                    self.assertEqual(r.returncode, 0, r.stdout[-2000:] + r.stderr[-3000:])
                    report = json.loads(r.stdout)
                    self.assertEqual(report["distributed"]["ranks"], count)
                    self.assertEqual(len(report["per_rank"]), count)
                    self.assertEqual(sum(p["controls_owned"] for p in report["per_rank"]), report["controls"])
                    got = gathered(out, count)
                    base = points(os.path.join(plain, "constant", "polyMesh"))
                    largest = np.abs(want - base).max()
                    self.assertGreater(largest, 0.01)
                    self.assertLess(np.abs(got - want).max(), 1e-10 * largest)
                    if poly == "none":
                        # Exact locality, serial and distributed: a point 2R or farther from every
                        # point of the airfoil (here of a box around it, a superset) keeps its bits.
                        self.assertEqual(report["reach"], 2 * radius)
                        # A staying point on a processor boundary is counted once, as in the serial run.
                        self.assertGreater(report["far_fixed"], 0)
                        self.assertEqual(report["far_fixed"], self.serial_report["far_fixed"])
                        near = base[(base[:, 0] >= -0.05) & (base[:, 0] <= 1.05) & (np.abs(base[:, 1]) <= 0.2)]
                        gap = np.array([np.sqrt(((near - p) ** 2).sum(axis=1)).min() for p in base])
                        far = gap >= 2 * radius
                        self.assertGreater(far.sum(), 100)
                        self.assertTrue(np.array_equal(want[far], base[far]))
                        # Against the processors' own points (decomposePar's 17 digits are 1 ulp off
                        # the case's in a few points).
                        self.assertTrue(np.array_equal(got[far], gathered(case, count)[far]))
                    else:
                        self.assertIsNone(report["reach"])
                    # OpenFOAM puts the processors back together and accepts the whole mesh.
                    r = run(["reconstructParMesh", "-constant"], cwd=out)
                    self.assertEqual(r.returncode, 0, r.stdout[-2000:])
                    self.check_mesh(out)
                    # The input case is untouched.
                    for k in range(count):
                        with open(os.path.join(case, "processor%d/constant/polyMesh/points" % k), "rb") as f:
                            self.assertEqual(f.read(), inputs[k])

    def test_greedy_on_a_decomposed_case_meets_its_tolerance(self):
        # Issue 31, point 4: greedy under mpirun. Each part adds its own worst points a round; the
        # rounds end together, every boundary point within the tolerance, the mesh valid.
        plain = self.airfoil("plain")
        want = self.serial(plain, self.path("serial"))
        case = self.path("case")
        shutil.copytree(plain, case)
        decompose(case, 2, "simple", "2 1 1")
        out = self.path("out")
        # An unbounded budget: under a loaded machine the rounds' budget (a share of the predicted
        # plain fit, at least 0.1 s) stopped greedy after its first round, one run in three.
        r = run(MPIRUN + ["2", CLI, "morph", case, "-o", out, "--motion", self.path("motion.json"), "--greedy", "1e-3",
                          "--greedy-budget", "1e6", "--json"])
        self.assertEqual(r.returncode, 0, r.stdout[-2000:] + r.stderr[-3000:])
        report = json.loads(r.stdout)
        self.assertGreater(report["greedy_rounds"], 1)
        self.assertIsNone(report["greedy_stopped"])
        self.assertLess(report["controls"], self.serial_report["controls"])
        self.assertLessEqual(report["max_boundary_error"], 1e-3 * report["max_displacement"])
        got = gathered(out, 2)
        largest = np.abs(want - points(os.path.join(plain, "constant", "polyMesh"))).max()
        self.assertLess(np.abs(got - want).max(), 0.05 * largest)
        self.assertEqual(run(["reconstructParMesh", "-constant"], cwd=out).returncode, 0)
        self.check_mesh(out)

    def test_pitzdaily_hierarchical_on_four_ranks(self):
        case = self.path("pitzDaily")
        shutil.copytree(os.path.join(TUTORIALS, "pitzDaily"), case)
        full_precision(case)
        r = run(["blockMesh"], cwd=case)
        self.assertEqual(r.returncode, 0, r.stdout[-2000:])
        with open(self.path("motion.json"), "w") as f:
            # No radius: auto, chosen alike by the serial run and by four parts from their gathered controls.
            json.dump({"patches": {"lowerWall": {"translate": [0, 0.0001, 0]}, "upperWall": "fixed",
                                   "inlet": "fixed", "outlet": "fixed"}}, f)
        plain = self.path("plain")
        shutil.copytree(case, plain)
        want = self.serial(plain, self.path("serial"))
        decompose(case, 4, "hierarchical", "2 2 1")
        out = self.path("out")
        r = run(MPIRUN + ["4", CLI, "morph", case, "-o", out, "--motion", self.path("motion.json"), "--json"])
        self.assertEqual(r.returncode, 0, r.stdout[-2000:] + r.stderr[-3000:])
        report = json.loads(r.stdout)
        self.assertEqual(report["radius"], self.serial_report["radius"])
        self.assertEqual(report["radius_why"], self.serial_report["radius_why"])
        self.assertIn("x the boundary's spacing", report["radius_why"])
        # The cell determinant counts the faces between processors as coupled, as checkMesh does:
        # the parts' figures make the serial one.
        for when in ("before", "after"):
            got_q = json.loads(r.stdout)["quality"][when]["polyhedra"]
            want_q = self.serial_report["quality"][when]["polyhedra"]
            self.assertAlmostEqual(got_q["min_determinant"], want_q["min_determinant"], delta=1e-9)
            self.assertAlmostEqual(got_q["mean_determinant"], want_q["mean_determinant"], delta=1e-9)
        largest = np.abs(want - points(os.path.join(plain, "constant", "polyMesh"))).max()
        self.assertLess(np.abs(gathered(out, 4) - want).max(), 1e-10 * largest)
        self.assertEqual(run(["reconstructParMesh", "-constant"], cwd=out).returncode, 0)
        self.check_mesh(out)

    def test_in_place_rewrites_each_processors_points(self):
        case = self.airfoil()
        decompose(case, 2, "simple", "2 1 1")
        copy = self.path("copy")
        r = run(MPIRUN + ["2", CLI, "morph", case, "-o", copy, "--motion", self.path("motion.json")])
        self.assertEqual(r.returncode, 0, r.stderr)
        before = {k: open(os.path.join(case, "processor%d/constant/polyMesh/faces" % k), "rb").read() for k in (0, 1)}
        r = run(MPIRUN + ["2", CLI, "morph", case, "--in-place", "--motion", self.path("motion.json")])
        self.assertEqual(r.returncode, 0, r.stderr)
        for k in (0, 1):
            for f in ("faces", "owner", "neighbour", "boundary"):
                a = open(os.path.join(case, "processor%d/constant/polyMesh" % k, f), "rb").read()
                b = open(os.path.join(copy, "processor%d/constant/polyMesh" % k, f), "rb").read()
                self.assertEqual(a, b, "processor%d %s" % (k, f))
            # The points equal the copy's to rounding (MUMPS need not add in the same order twice).
            a = points(os.path.join(case, "processor%d/constant/polyMesh" % k))
            b = points(os.path.join(copy, "processor%d/constant/polyMesh" % k))
            self.assertLess(np.abs(a - b).max(), 1e-14)
            self.assertEqual(before[k], open(os.path.join(case, "processor%d/constant/polyMesh/faces" % k), "rb").read())
        self.assertEqual([f for f in os.listdir(os.path.join(case, "processor1/constant/polyMesh")) if "csrbf" in f], [])

    def test_a_bad_processor_fails_every_rank_and_nothing_is_written(self):
        case = self.airfoil()
        decompose(case, 3, "simple", "3 1 1")
        pts = os.path.join(case, "processor1", "constant", "polyMesh", "points")
        with open(pts) as f:
            text = f.read()

        with open(pts, "w") as f:
            f.write(text[:len(text) // 2])  # truncated on rank 1 only
        out = self.path("out")
        r = run(MPIRUN + ["3", CLI, "morph", case, "-o", out, "--motion", self.path("motion.json")])
        self.assertEqual(r.returncode, 1, r.stdout + r.stderr)
        self.assertIn("processor1", r.stderr)
        self.assertEqual(r.stderr.count("csrbf: error"), 1, r.stderr)  # one message, from rank 0
        self.assertFalse(os.path.exists(out))
        self.assertEqual([f for f in os.listdir(self.tmp) if f.startswith(".out") or "partial" in f], [])
        # In place: every processor's points stay as they were.
        before = open(os.path.join(case, "processor0/constant/polyMesh/points"), "rb").read()
        r = run(MPIRUN + ["3", CLI, "morph", case, "--in-place", "--motion", self.path("motion.json")])
        self.assertEqual(r.returncode, 1)
        self.assertEqual(before, open(os.path.join(case, "processor0/constant/polyMesh/points"), "rb").read())
        # A patch the mesh does not have: the same error on every rank, said once.
        with open(self.path("bad.json"), "w") as f:
            json.dump({"radius": 1.5, "patches": {"wing": "fixed"}}, f)
        with open(pts, "w") as f:
            f.write(text)
        r = run(MPIRUN + ["3", CLI, "morph", case, "-o", out, "--motion", self.path("bad.json")])
        self.assertEqual(r.returncode, 1)
        self.assertIn("wing", r.stderr)
        self.assertFalse(os.path.exists(out))

    def test_what_the_attack_found(self):
        """Hangs, torn meshes and silent partial morphs a trial found, each now an error or right."""
        case = self.airfoil()
        decompose(case, 3, "simple", "3 1 1")
        motion = self.path("motion.json")
        # A rank over the memory limit while the others assemble: an error, not a hang.
        r = run(MPIRUN + ["3", CLI, "morph", case, "-o", self.path("o1"), "--motion", motion, "--memory-limit", "1.95e-4"])
        self.assertEqual(r.returncode, 1, r.stderr)
        self.assertIn("limit", r.stderr)
        # One processor with a point beyond 1e150: an error, not a hang.
        bad = self.path("big")
        shutil.copytree(case, bad)
        pts = os.path.join(bad, "processor1", "constant", "polyMesh", "points")
        with open(pts) as f:
            lines = f.read().split("\n")
        lines[lines.index("(") + 1] = "(1e300 1e300 1e300)"
        with open(pts, "w") as f:
            f.write("\n".join(lines))
        r = run(MPIRUN + ["3", CLI, "morph", bad, "-o", self.path("o2"), "--motion", motion])
        self.assertEqual(r.returncode, 1, r.stderr)
        self.assertFalse(os.path.exists(self.path("o2")))
        # Missing -o: one usage error.
        r = run(MPIRUN + ["3", CLI, "morph", case, "--motion", motion])
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertEqual(r.stderr.count("csrbf: error"), 1, r.stderr)
        # An inverting motion: said once, nothing written.
        with open(self.path("inv.json"), "w") as f:
            json.dump({"radius": 0.2, "patches": {"airfoil": {"rotate": {"axis": [0, 0, 1], "degrees": 60,
                                                                         "origin": [0.25, 0, 0]}},
                                                  "farfield": "fixed"}}, f)
        r = run(MPIRUN + ["3", CLI, "morph", case, "-o", self.path("o3"), "--motion", self.path("inv.json")])
        self.assertEqual(r.returncode, 1)
        self.assertEqual(r.stderr.count("csrbf: error"), 1, r.stderr)
        self.assertFalse(os.path.exists(self.path("o3")))
        # A displacements file (the airfoil's points, each moved up) with a point no part has on the patch.
        poly = os.path.join(self.path("plain-d"), "constant", "polyMesh")
        shutil.copytree(os.path.join(SOURCE, "examples", "airfoil", "case"), self.path("plain-d"))
        n, body = foam_list(os.path.join(poly, "faces"))
        faces = [[int(v) for v in f.split()] for f in re.findall(r"\d+\(([\d ]+)\)", body)[:n]]
        with open(os.path.join(poly, "boundary")) as f:
            m = re.search(r"airfoil\s*\{[^}]*nFaces\s+(\d+);\s*startFace\s+(\d+);", f.read())
        count, start = int(m.group(1)), int(m.group(2))
        ids = sorted({v for face in faces[start:start + count] for v in face})
        with open(self.path("d.txt"), "w") as f:
            f.writelines("%d 0 0.001 0\n" % i for i in ids)
            f.write("99999 0.1 0 0\n")
        with open(self.path("dm.json"), "w") as f:
            json.dump({"radius": 1.5, "patches": {"airfoil": {"displacements": "d.txt"}, "farfield": "fixed"}}, f)
        r = run(MPIRUN + ["3", CLI, "morph", case, "-o", self.path("o4"), "--motion", self.path("dm.json")])
        self.assertEqual(r.returncode, 1, r.stderr)
        self.assertIn("99999", r.stderr)
        # A case whose processor polyMesh links elsewhere: the copy does not write through the link.
        linked = self.path("linked")
        shutil.copytree(case, linked)
        poly = os.path.join(linked, "processor1", "constant", "polyMesh")
        shutil.move(poly, self.path("elsewhere"))
        os.symlink(self.path("elsewhere"), poly)
        before = open(os.path.join(self.path("elsewhere"), "points"), "rb").read()
        r = run(MPIRUN + ["3", CLI, "morph", linked, "-o", self.path("o5"), "--motion", motion])
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(before, open(os.path.join(self.path("elsewhere"), "points"), "rb").read())
        self.assertFalse(os.path.islink(os.path.join(self.path("o5"), "processor1", "constant", "polyMesh")))
        # A missing processor folder (the dictionary says 3).
        gone = self.path("gone")
        shutil.copytree(case, gone)
        shutil.rmtree(os.path.join(gone, "processor2"))
        r = run(MPIRUN + ["2", CLI, "morph", gone, "-o", self.path("o6"), "--motion", motion])
        self.assertEqual(r.returncode, 1, r.stderr)
        self.assertIn("numberOfSubdomains", r.stderr)
        shutil.rmtree(os.path.join(gone, "processor1"))
        shutil.copytree(os.path.join(case, "processor2"), os.path.join(gone, "processor2"))
        r = run(MPIRUN + ["1", CLI, "morph", gone, "-o", self.path("o7"), "--motion", motion])
        # One rank is the serial program: it warns that the processor folders stay as they are.
        self.assertIn("processor folders", r.stderr)

    def test_an_empty_processor_and_an_in_place_that_cannot_finish(self):
        case = self.airfoil()
        with open(os.path.join(case, "constant", "cellDecomposition"), "w") as f:
            f.write("FoamFile { version 2.0; format ascii; class labelList; object cellDecomposition; }\n3840\n(\n" +
                    "\n".join("0" if i < 1920 else "1" for i in range(3840)) + "\n)\n")
        with open(os.path.join(case, "system", "decomposeParDict"), "w") as f:
            f.write("FoamFile { version 2.0; format ascii; class dictionary; object decomposeParDict; }\n"
                    "numberOfSubdomains 3;\nmethod manual;\nmanualCoeffs { dataFile \"cellDecomposition\"; }\n")
        self.assertEqual(run(["decomposePar", "-force"], cwd=case).returncode, 0)
        plain = self.airfoil("plain")
        want = self.serial(plain, self.path("serial"))
        out = self.path("out")
        r = run(MPIRUN + ["3", CLI, "morph", case, "-o", out, "--motion", self.path("motion.json"), "--json"])
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(json.loads(r.stdout)["cells"], 3840)
        largest = np.abs(want - points(os.path.join(plain, "constant", "polyMesh"))).max()
        got = gathered(out, 2)  # processor2 has no points
        self.assertLess(np.abs(got - want).max(), 1e-10 * largest)
        # In place, where one part cannot be renamed (immutable): every part stays as it was.
        target = os.path.join(case, "processor1", "constant", "polyMesh", "points")
        if subprocess.run(["chattr", "+i", target], capture_output=True).returncode != 0:
            self.skipTest("chattr +i is not available here")
        self.addCleanup(lambda: subprocess.run(["chattr", "-i", target]))
        before = [open(os.path.join(case, "processor%d/constant/polyMesh/points" % k), "rb").read() for k in range(3)]
        r = run(MPIRUN + ["3", CLI, "morph", case, "--in-place", "--motion", self.path("motion.json")])
        self.assertEqual(r.returncode, 1, r.stderr)
        subprocess.run(["chattr", "-i", target])
        for k in range(3):
            self.assertEqual(before[k], open(os.path.join(case, "processor%d/constant/polyMesh/points" % k), "rb").read())
            self.assertEqual([f for f in os.listdir(os.path.join(case, "processor%d/constant/polyMesh" % k))
                              if "csrbf" in f], [])

    def test_the_wrong_number_of_ranks_is_a_usage_error(self):
        case = self.airfoil()
        decompose(case, 2, "simple", "2 1 1")
        r = run(MPIRUN + ["3", CLI, "morph", case, "-o", self.path("out"), "--motion", self.path("motion.json")])
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn("mpirun -np 2", r.stderr)
        self.assertFalse(os.path.exists(self.path("out")))

    def box_pieces(self, parts):
        """A box of hexahedra (12 x 6 x 4 cells) as one .vtu and as a .pvtu of `parts` slabs of
        cells (their shared points repeated in each), with a point array "patch": 1 on the bottom,
        2 on the top."""
        import vtk
        from vtk.util import numpy_support as ns
        nx, ny, nz, h = 12, 6, 4, 0.1

        def grid(i0, i1):
            pts = [(i * h, j * h, k * h) for k in range(nz + 1) for j in range(ny + 1) for i in range(i0, i1 + 1)]
            w = i1 - i0 + 1
            idx = lambda i, j, k: (i - i0) + w * (j + (ny + 1) * k)
            g = vtk.vtkUnstructuredGrid()
            p = vtk.vtkPoints()
            p.SetData(ns.numpy_to_vtk(np.array(pts, dtype=float), deep=True))
            g.SetPoints(p)
            for k in range(nz):
                for j in range(ny):
                    for i in range(i0, i1):
                        ids = [idx(i, j, k), idx(i + 1, j, k), idx(i + 1, j + 1, k), idx(i, j + 1, k),
                               idx(i, j, k + 1), idx(i + 1, j, k + 1), idx(i + 1, j + 1, k + 1), idx(i, j + 1, k + 1)]
                        g.InsertNextCell(vtk.VTK_HEXAHEDRON, 8, ids)
            z = np.array(pts)[:, 2]
            patch = np.where(z == 0, 1, np.where(np.isclose(z, nz * h), 2, 0)).astype(np.int32)
            a = ns.numpy_to_vtk(patch, deep=True)
            a.SetName("patch")
            g.GetPointData().AddArray(a)
            return g

        def write(g, path):
            w = vtk.vtkXMLUnstructuredGridWriter()
            w.SetFileName(path)
            w.SetInputData(g)
            w.SetDataModeToBinary()
            assert w.Write() == 1

        whole = self.path("box.vtu")
        write(grid(0, nx), whole)
        os.makedirs(self.path("box"))
        cuts = [round(nx * r / parts) for r in range(parts + 1)]
        pieces = []
        for r in range(parts):
            name = "box_%d.vtu" % r
            write(grid(cuts[r], cuts[r + 1]), self.path("box", name))
            pieces.append('    <Piece Source="box/%s"/>' % name)
        with open(self.path("box.pvtu"), "w") as f:
            f.write('<?xml version="1.0"?>\n<VTKFile type="PUnstructuredGrid" version="0.1" byte_order="LittleEndian">\n'
                    '  <PUnstructuredGrid GhostLevel="0">\n    <PPointData><PDataArray type="Int32" Name="patch"/>'
                    '</PPointData>\n    <PPoints><PDataArray type="Float64" NumberOfComponents="3"/></PPoints>\n'
                    + "\n".join(pieces) + '\n  </PUnstructuredGrid>\n</VTKFile>\n')
        with open(self.path("box.json"), "w") as f:
            json.dump({"radius": 0.35, "kernel": "c2", "patch_array": "patch",
                       "patches": {"1": {"translate": [0.01, 0, 0.03]}, "2": "fixed"}}, f)
        return whole

    def vtu_points(self, path):
        import vtk
        from vtk.util import numpy_support as ns
        r = vtk.vtkXMLUnstructuredGridReader()
        r.SetFileName(path)
        r.Update()
        return ns.vtk_to_numpy(r.GetOutput().GetPoints().GetData()).astype(float)

    def test_pvtu_pieces_equal_the_serial_morph(self):
        for parts in (2, 3):
            with self.subTest(pieces=parts):
                shutil.rmtree(self.tmp)
                os.makedirs(self.tmp)
                whole = self.box_pieces(parts)
                r = run([CLI, "morph", whole, "-o", self.path("serial.vtu"), "--motion", self.path("box.json")])
                self.assertEqual(r.returncode, 0, r.stderr)
                base, want = self.vtu_points(whole), self.vtu_points(self.path("serial.vtu"))
                moved = {tuple(p): q for p, q in zip(base, want)}
                r = run(MPIRUN + [str(parts), CLI, "morph", self.path("box.pvtu"), "-o", self.path("out.pvtu"),
                                  "--motion", self.path("box.json"), "--json"])
                self.assertEqual(r.returncode, 0, r.stdout[-2000:] + r.stderr[-3000:])
                self.assertEqual(json.loads(r.stdout)["distributed"]["ranks"], parts)
                largest = np.abs(want - base).max()
                self.assertGreater(largest, 0.02)
                with open(self.path("out.pvtu")) as f:
                    self.assertEqual(f.read().count('Source="out/box_'), parts)
                for k in range(parts):
                    before = self.vtu_points(self.path("box", "box_%d.vtu" % k))
                    after = self.vtu_points(self.path("out", "box_%d.vtu" % k))
                    expect = np.array([moved[tuple(p)] for p in before])
                    self.assertLess(np.abs(after - expect).max(), 1e-10 * largest)
                # In place: each piece rewritten, equal to the copy's (to rounding: MUMPS's parallel
                # factorisation need not add in the same order twice).
                r = run(MPIRUN + [str(parts), CLI, "morph", self.path("box.pvtu"), "--in-place",
                                  "--motion", self.path("box.json")])
                self.assertEqual(r.returncode, 0, r.stderr)
                for k in range(parts):
                    a = self.vtu_points(self.path("box", "box_%d.vtu" % k))
                    b = self.vtu_points(self.path("out", "box_%d.vtu" % k))
                    self.assertLess(np.abs(a - b).max(), 1e-12 * largest, (k, np.abs(a - b).max()))
                self.assertEqual([f for f in os.listdir(self.path("box")) if "csrbf" in f], [])
                # The wrong number of ranks, and a missing piece.
                r = run(MPIRUN + [str(parts + 1), CLI, "morph", self.path("box.pvtu"), "-o", self.path("x.pvtu"),
                                  "--motion", self.path("box.json")])
                self.assertEqual(r.returncode, 2, r.stderr)
                self.assertIn("mpirun -np %d" % parts, r.stderr)
                os.remove(self.path("box", "box_1.vtu"))
                r = run(MPIRUN + [str(parts), CLI, "morph", self.path("box.pvtu"), "-o", self.path("y.pvtu"),
                                  "--motion", self.path("box.json")])
                self.assertEqual(r.returncode, 1, r.stderr)
                self.assertIn("box_1.vtu", r.stderr)
                self.assertFalse(os.path.exists(self.path("y.pvtu")) or os.path.exists(self.path("y")))

    def test_a_single_mesh_is_spread_from_rank_zero(self):
        plain = self.airfoil("plain")
        want = self.serial(plain, self.path("serial"))
        for count in (2, 3):
            out = self.path("out%d" % count)
            r = run(MPIRUN + [str(count), CLI, "morph", plain, "-o", out, "--motion", self.path("motion.json"), "--json"])
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertEqual(json.loads(r.stdout)["distributed"]["ranks"], count)
            largest = np.abs(want - points(os.path.join(plain, "constant", "polyMesh"))).max()
            self.assertLess(np.abs(points(os.path.join(out, "constant", "polyMesh")) - want).max(), 1e-10 * largest)
        # deform: the bundled bunny, every kernel, against the serial program.
        bunny, controls = os.path.join(SOURCE, "examples", "bunny.obj"), os.path.join(SOURCE, "examples", "bunny.controls")

        def vertices(path):
            with open(path) as f:
                return np.array([[float(x) for x in l.split()[1:4]] for l in f if l.startswith("v ")])
        for kernel in ("c0", "c2", "c4", "c6"):
            for poly in ("none", "linear"):
                a, b = self.path("a-%s-%s.obj" % (kernel, poly)), self.path("b-%s-%s.obj" % (kernel, poly))
                args = ["deform", "-m", bunny, "--controls", controls, "-r", "2.5", "-k", kernel, "-p", poly]
                self.assertEqual(run([CLI] + args + ["-o", a]).returncode, 0)
                r = run(MPIRUN + ["3", CLI] + args + ["-o", b])
                self.assertEqual(r.returncode, 0, r.stderr)
                va, vb, v0 = vertices(a), vertices(b), vertices(bunny)
                self.assertLess(np.abs(va - vb).max(), 1e-10 * np.abs(va - v0).max(), (kernel, poly))


class Signals(unittest.TestCase):
    """Issue 30: SIGTERM or SIGINT to mpirun while the ranks write wrote the output anyway (mpirun
    sends its ranks SIGCONT, then SIGTERM a second later: time enough to finish). A rank now takes
    its launcher's SIGCONT as the end: no output, no partial, no process left."""

    def test_a_signal_to_mpirun_writes_nothing(self):
        import signal
        import time
        tmp = tempfile.mkdtemp(prefix="csrbf-mpi-signal-")
        self.addCleanup(shutil.rmtree, tmp, True)
        rng = np.random.default_rng(30)
        with open(os.path.join(tmp, "big.ply"), "w") as f:
            p = rng.random((1000000, 3))
            f.write("ply\nformat ascii 1.0\nelement vertex %d\nproperty float x\nproperty float y\n"
                    "property float z\nend_header\n" % len(p))
            np.savetxt(f, p, fmt="%.6f")
        controls = os.path.join(SOURCE, "examples", "fish.controls")
        judged = 0
        for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGTERM, signal.SIGINT):
            out = os.path.join(tmp, "out.ply")
            proc = subprocess.Popen(MPIRUN + ["2", CLI, "deform", "--mesh", os.path.join(tmp, "big.ply"),
                                              "--controls", controls, "--radius", "0.3", "-o", out],
                                    env=ENV, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
            # The signal comes once while rank 0 writes (its partial file is there), as one Ctrl-C
            # does (a second one within 5 s makes mpirun kill its ranks at once, as kill -9 would:
            # then the partial stays for the next run to remove).
            sent = False
            deadline = time.time() + 300
            while proc.poll() is None and time.time() < deadline:
                if not sent and any(".csrbf-partial-" in n for n in os.listdir(tmp)):
                    proc.send_signal(sig)
                    sent = True
                time.sleep(0.005)
            proc.communicate(timeout=60)
            if not sent:
                continue  # it finished between two looks: nothing to judge
            judged += 1
            self.assertNotEqual(proc.returncode, 0, sig)
            self.assertFalse(os.path.exists(out), sig)
            time.sleep(0.5)
            left = subprocess.run(["pgrep", "-f", out], capture_output=True, text=True).stdout.split()
            self.assertEqual(left, [], "ranks left running after mpirun ended")
            self.assertEqual([n for n in os.listdir(tmp) if "csrbf-partial" in n], [])
        self.assertGreater(judged, 0, "no signal came while rank 0 wrote")

if __name__ == "__main__":
    unittest.main()
