"""csrbf morph judged by OpenFOAM's own tools (Debian's openfoam 1912): checkMesh on the morphed
bundled example, the airFoil2D tutorial and pitzDaily after blockMesh, in ASCII, binary and gzip;
every byte but the coordinates kept; csrbf's quality figures equal to checkMesh's; bad input
refused with nothing written.

    CSRBF_CLI=build/bin/csrbf CSRBF_SOURCE_DIR=. /usr/bin/python3 -m unittest -v test_openfoam
"""
import gzip
import json
import math
import os
import re
import shutil
import subprocess
import unittest

from morph_case import MorphCase

CLI = os.environ.get("CSRBF_CLI", "csrbf")
SOURCE = os.environ.get("CSRBF_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
TUTORIALS = "/usr/share/doc/openfoam-examples/examples/incompressible/simpleFoam"
ENV = dict(os.environ, WM_PROJECT_DIR="/usr/share/openfoam", OMPI_ALLOW_RUN_AS_ROOT="1",
           OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMPI_MCA_plm_rsh_agent="")


def run(args, cwd=None):
    return subprocess.run(args, cwd=cwd, env=ENV, capture_output=True, text=True, timeout=600)


def check_mesh(case):
    """checkMesh's figures and its verdict."""
    r = run(["checkMesh"], cwd=case)
    out = r.stdout + r.stderr
    m = re.search(r"Mesh non-orthogonality Max: (\S+) average: (\S+)", out)
    s = re.search(r"Max skewness = ([-+.0-9eE]+)", out)
    v = re.search(r"Min volume = (\S+)\.\s", out) or re.search(r"Minimum negative volume: (\S+),", out)
    failed = re.search(r"Failed (\d+) mesh checks", out)
    # The geometry section alone: "***" marks a failed check.
    geometry = out.split("Checking geometry...")[-1]
    return {"ok": "Mesh OK." in out, "failed": int(failed.group(1)) if failed else 0,
            "max_non_orth": float(m.group(1)), "mean_non_orth": float(m.group(2)),
            "max_skewness": float(s.group(1)), "min_volume": float(v.group(1)),
            "geometry_errors": geometry.count("***"), "text": out}


def read_text(path):
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rb") as f:
        return f.read()


def morph(case, out, motion, *extra):
    return run([CLI, "morph", case, "-o", out, "--motion", motion, "--json", *extra])


def tree_files(root):
    out = {}
    for d, _, files in os.walk(root):
        for f in files:
            p = os.path.join(d, f)
            out[os.path.relpath(p, root)] = p
    return out


class OpenFoamCases(MorphCase):

    def assert_kept(self, case, out, changed=("points", "points.gz")):
        """Every file but points is a byte-for-byte copy; points keeps its header."""
        a, b = tree_files(case), tree_files(out)
        self.assertEqual(sorted(a), sorted(b))
        for rel, p in a.items():
            if os.path.basename(rel) in changed and "polyMesh" in rel:
                old, new = read_text(p), read_text(b[rel])
                head = old.index(b"(")
                self.assertEqual(old[:head], new[:head], rel)
                continue
            with open(p, "rb") as x, open(b[rel], "rb") as y:
                self.assertEqual(x.read(), y.read(), rel)

    def assert_quality_matches(self, report, cm):
        q = report["quality"]["after"]["polyhedra"]
        self.assertAlmostEqual(q["max_non_orthogonality"], cm["max_non_orth"], delta=1e-4 * max(1, cm["max_non_orth"]))
        self.assertAlmostEqual(q["mean_non_orthogonality"], cm["mean_non_orth"], delta=1e-4 * max(1, cm["mean_non_orth"]))
        self.assertAlmostEqual(q["max_skewness"], cm["max_skewness"], delta=1e-4 * max(1, cm["max_skewness"]))
        self.assertAlmostEqual(q["min_volume"], cm["min_volume"], delta=1e-5 * abs(cm["min_volume"]))

    def assert_determinant_matches(self, report, case):
        """The cell determinant against checkMesh -allGeometry's (a 2-D mesh: its empty direction)."""
        copy = case + "-checked"  # checkMesh -allGeometry writes sets of faces into the case
        shutil.copytree(case, copy)
        out = run(["checkMesh", "-allGeometry"], cwd=copy).stdout
        shutil.rmtree(copy)
        d = re.search(r"Cell determinant \(wellposedness\) : minimum: (\S+) average: (\S+)", out)
        self.assertIsNotNone(d, out[-3000:])
        q = report["quality"]["after"]["polyhedra"]
        self.assertAlmostEqual(q["min_determinant"], float(d.group(1)), delta=2e-6 * float(d.group(1)))  # printed to 6 digits or more
        self.assertAlmostEqual(q["mean_determinant"], float(d.group(2)), delta=2e-6 * float(d.group(2)))

    def test_bundled_airfoil_pitches_and_passes_check_mesh(self):
        case = os.path.join(SOURCE, "examples", "airfoil", "case")
        out = os.path.join(self.tmp, "pitched")
        r = morph(case, out, os.path.join(SOURCE, "examples", "airfoil", "motion.json"))
        self.assertEqual(r.returncode, 0, r.stderr)
        report = json.loads(r.stdout)
        self.assertTrue(report["written"])
        self.assertEqual(report["points"], 7872)
        self.assertEqual(report["cells"], 3840)
        cm = check_mesh(out)
        self.assertTrue(cm["ok"], cm["text"])
        self.assert_quality_matches(report, cm)
        self.assert_determinant_matches(report, out)
        self.assert_kept(case, out)
        # The airfoil's points are rotated by exactly -5 degrees about (0.25, 0, 0), to 1e-12 of the
        # domain; the far field's are unchanged bit for bit (the same text).
        old = read_text(os.path.join(case, "constant/polyMesh/points")).decode().split("\n")
        new = read_text(os.path.join(out, "constant/polyMesh/points")).decode().split("\n")
        first = old.index("(") + 1
        import math
        c, s = math.cos(math.radians(-5)), math.sin(math.radians(-5))
        ring = 96
        for k in range(2):  # back and front planes
            for i in range(ring):
                row = first + k * ring * 41 + i
                x, y, z = map(float, old[row].strip("()").split())
                nx, ny, nz = map(float, new[row].strip("()").split())
                ex, ey = 0.25 + c * (x - 0.25) - s * y, s * (x - 0.25) + c * y
                self.assertLess(math.hypot(nx - ex, ny - ey), 1e-12 * 40, (x, y))
                self.assertEqual(nz, z)
                far = first + k * ring * 41 + 40 * ring + i
                self.assertEqual(old[far], new[far])

    def test_airfoil2d_gzip_keeps_its_format_and_its_checks(self):
        case = os.path.join(self.tmp, "airFoil2D")
        shutil.copytree(os.path.join(TUTORIALS, "airFoil2D"), case)
        before = check_mesh(case)
        out = os.path.join(self.tmp, "airFoil2D-pitched")
        motion = self.motion({"radius": 20, "patches": {
            "walls": {"rotate": {"axis": [0, 0, 1], "degrees": -3, "origin": [-8.75, 0, 0]}},
            "inlet": "fixed", "outlet": "fixed"}})
        r = morph(case, out, motion)
        self.assertEqual(r.returncode, 0, r.stderr)
        report = json.loads(r.stdout)
        self.assertEqual(report["encoding"], "ascii, gzip")
        self.assertLess(report["ms"]["total"], 5000)
        self.assertTrue(os.path.exists(os.path.join(out, "constant/polyMesh/points.gz")))
        self.assertFalse(os.path.exists(os.path.join(out, "constant/polyMesh/points")))
        cm = check_mesh(out)
        # The tutorial's faces are not in upper triangular order (a topology check it fails as
        # shipped, which no morph changes): every geometry check passes, as before.
        self.assertEqual(before["geometry_errors"], 0)
        self.assertEqual(cm["geometry_errors"], 0, cm["text"])
        self.assertEqual(cm["failed"], before["failed"])
        self.assertIn("Faces not in upper triangular order", before["text"])
        self.assert_quality_matches(report, cm)
        self.assert_kept(case, out)

    def pitz_daily(self, binary=False, compress=False):
        case = os.path.join(self.tmp, "pitzDaily" + ("-binary" if binary else "") + ("-gz" if compress else ""))
        shutil.copytree(os.path.join(TUTORIALS, "pitzDaily"), case)
        r = run(["blockMesh"], cwd=case)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        if binary:
            control = os.path.join(case, "system", "controlDict")
            with open(control) as f:
                text = f.read()
            with open(control, "w") as f:
                f.write(re.sub(r"writeFormat\s+\w+;", "writeFormat binary;", text))
            r = run(["foamFormatConvert", "-constant"], cwd=case)
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        if compress:
            poly = os.path.join(case, "constant", "polyMesh")
            for name in ("points", "faces", "owner", "neighbour"):
                subprocess.run(["gzip", os.path.join(poly, name)], check=True)
        return case

    def test_pitz_daily_in_every_encoding_passes_check_mesh_and_agrees(self):
        motion = self.motion({"radius": 0.03, "patches": {
            "lowerWall": {"translate": [0, 0.0003, 0]}, "upperWall": "fixed", "inlet": "fixed", "outlet": "fixed"}})
        results = {}
        for binary, compress in ((False, False), (True, False), (False, True), (True, True)):
            case = self.pitz_daily(binary, compress)
            if binary:
                self.assertIn(b"format      binary", read_text(os.path.join(
                    case, "constant/polyMesh/points" + (".gz" if compress else ""))))
            out = case + "-morphed"
            r = morph(case, out, motion)
            self.assertEqual(r.returncode, 0, r.stderr)
            report = json.loads(r.stdout)
            self.assertEqual(report["encoding"], ("binary" if binary else "ascii") + (", gzip" if compress else ""))
            cm = check_mesh(out)
            self.assertTrue(cm["ok"], cm["text"])
            self.assert_quality_matches(report, cm)
            self.assert_kept(case, out)
            results[(binary, compress)] = report["quality"]["after"]["polyhedra"]
        # The same mesh in four encodings morphs to the same quality.
        first = results[(False, False)]
        for q in results.values():
            self.assertAlmostEqual(q["max_non_orthogonality"], first["max_non_orthogonality"], places=9)
            self.assertAlmostEqual(q["min_volume"], first["min_volume"], delta=1e-12 * abs(first["min_volume"]))

    def test_inverting_motion_writes_nothing_and_names_the_safe_phase(self):
        case = self.pitz_daily()
        motion = self.motion({"radius": 0.02, "patches": {
            "lowerWall": {"translate": [0, 0.002, 0]}, "upperWall": "fixed", "inlet": "fixed", "outlet": "fixed"}})
        out = os.path.join(self.tmp, "inverted")
        r = morph(case, out, motion)
        self.assertEqual(r.returncode, 1)
        self.assertIn("inverts", r.stderr)
        self.assertIn("nothing written", r.stderr)
        report = json.loads(r.stdout)
        self.assertFalse(report["written"])
        self.assertGreater(report["quality"]["after"]["inverted_cells"], 0)
        self.assertEqual(report["quality"]["before"]["inverted_cells"], 0)
        self.assertFalse(os.path.exists(out))
        self.assertEqual([f for f in os.listdir(self.tmp) if "partial" in f], [])
        safe = report["safe_phase"]
        self.assertGreater(safe, 0.0)
        self.assertLess(safe, 1.0)
        # At the safe phase the morph passes checkMesh's volume and pyramid checks.
        r = morph(case, out, motion, "--phase", repr(safe))
        self.assertEqual(r.returncode, 0, r.stderr)
        cm = check_mesh(out)
        self.assertNotIn("negative volume", cm["text"])
        self.assertIn("Face pyramids OK", cm["text"])
        # --force writes the inverted mesh, and checkMesh then agrees it is inverted.
        forced = os.path.join(self.tmp, "forced")
        r = morph(case, forced, motion, "--force")
        self.assertEqual(r.returncode, 0, r.stderr)
        cm = check_mesh(forced)
        self.assertFalse(cm["ok"])
        self.assertIn("Number of negative volume cells: %d" % json.loads(r.stdout)["quality"]["after"]["polyhedra"]["negative_volumes"],
                      cm["text"])

    def test_in_place_rewrites_points_alone(self):
        case = self.pitz_daily()
        poly = os.path.join(case, "constant", "polyMesh")
        faces = read_text(os.path.join(poly, "faces"))
        motion = self.motion({"radius": 0.03, "patches": {"lowerWall": {"translate": [0, 0.0003, 0]}, "upperWall": "fixed"}})
        r = run([CLI, "morph", case, "--in-place", "--motion", motion])
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(read_text(os.path.join(poly, "faces")), faces)
        self.assertEqual(sorted(os.listdir(poly)), ["boundary", "faces", "neighbour", "owner", "points"])
        self.assertTrue(check_mesh(case)["ok"])

    def test_time_folders_are_read_and_written_as_openfoam_does(self):
        # Issue 31, point 6: a case whose mesh already moved (a time folder with polyMesh/points) is
        # morphed from that mesh, and the moved points go into the time folder; constant/ stays.
        case = self.pitz_daily()
        poly = os.path.join(case, "constant", "polyMesh")
        constant_points = read_text(os.path.join(poly, "points"))
        motion = self.motion({"radius": 0.03, "patches": {"lowerWall": {"translate": [0, 0.0003, 0]},
                                                          "upperWall": "fixed"}})
        # No such time: an error that lists the case's times; nothing written.
        r = run([CLI, "morph", case, "--in-place", "-time", "0.1", "--motion", motion])
        self.assertEqual(r.returncode, 1, r.stderr)
        self.assertIn("no time folder 0.1; the case's times: 0", r.stderr)
        # A time folder without a mesh of its own reads constant's (as OpenFOAM does) and gets the
        # moved points.
        os.mkdir(os.path.join(case, "0.1"))
        r = run([CLI, "morph", case, "--in-place", "-time", "0.1", "--motion", motion, "--json"])
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(json.loads(r.stdout)["time"], "0.1")
        self.assertEqual(read_text(os.path.join(poly, "points")), constant_points)
        moved = os.path.join(case, "0.1", "polyMesh", "points")
        self.assertTrue(os.path.exists(moved))
        cm = run(["checkMesh", "-time", "0.1"], cwd=case)
        self.assertIn("Mesh OK.", cm.stdout, cm.stdout[-2000:])
        # The next morph, of the latest time (OpenFOAM's -latestTime), starts from that moved mesh:
        # the lower wall has moved twice.
        out = os.path.join(self.tmp, "twice")
        moved_before = read_text(moved)
        r = run([CLI, "morph", case, "-o", out, "-latestTime", "--motion", motion, "--json"])
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(json.loads(r.stdout)["time"], "0.1")
        self.assertEqual(read_text(os.path.join(out, "constant", "polyMesh", "points")), constant_points)
        self.assertEqual(read_text(moved), moved_before)  # the input's time folder is not written

        def lower_wall_y(points_file):
            text = read_text(points_file).decode()
            pts = re.findall(r"^\(([-+.0-9eE]+) ([-+.0-9eE]+) ([-+.0-9eE]+)\)$", text, re.M)
            return [float(p[1]) for p in pts]

        first = lower_wall_y(os.path.join(poly, "points"))
        second = lower_wall_y(os.path.join(out, "0.1", "polyMesh", "points"))
        once = lower_wall_y(moved)
        moved_twice = [i for i in range(len(first)) if abs(second[i] - first[i] - 0.0006) < 1e-12]
        moved_once = [i for i in range(len(first)) if abs(once[i] - first[i] - 0.0003) < 1e-12]
        self.assertGreater(len(moved_once), 100)
        self.assertEqual(moved_twice, moved_once)
        cm = run(["checkMesh", "-time", "0.1"], cwd=out)
        self.assertIn("Mesh OK.", cm.stdout, cm.stdout[-2000:])
        # A later time without a mesh of its own (a solver wrote it) reads the latest earlier time's
        # points, as OpenFOAM's findInstance does, not constant's: the wall moves from 0.1's mesh.
        os.mkdir(os.path.join(case, "0.2"))
        later = os.path.join(self.tmp, "later")
        r = run([CLI, "morph", case, "-o", later, "-time", "0.2", "--motion", motion, "--json"])
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(json.loads(r.stdout)["time"], "0.2")
        self.assertEqual(lower_wall_y(os.path.join(later, "0.2", "polyMesh", "points")), second)
        cm = run(["checkMesh", "-time", "0.2"], cwd=later)
        self.assertIn("Mesh OK.", cm.stdout, cm.stdout[-2000:])
        # A mesh file has no times.
        vtu = os.path.join(SOURCE, "examples", "vtk")
        files = [f for f in os.listdir(vtu) if f.endswith(".vtu")]
        if files:
            r = run([CLI, "morph", os.path.join(vtu, files[0]), "-o", os.path.join(self.tmp, "x.vtu"),
                     "-time", "latest", "--motion", motion])
            self.assertEqual(r.returncode, 1, r.stderr)
            self.assertIn("this is a mesh file, which has no times", r.stderr)

    def test_a_3d_cavity_with_a_graded_lid_reports_checkmeshs_determinant(self):
        # The cavity tutorial made 3-D (8 cells deep, graded, its front and back walls) and its lid
        # pushed in: the cell determinant counts every internal face, in three directions.
        case = os.path.join(self.tmp, "cavity3d")
        shutil.copytree(os.path.join(os.path.dirname(TUTORIALS), "..", "incompressible", "icoFoam", "cavity", "cavity"),
                        case)
        mesh_dict = os.path.join(case, "system", "blockMeshDict")
        text = read_text(mesh_dict).decode()
        text = text.replace("(20 20 1) simpleGrading (1 1 1)", "(12 10 8) simpleGrading (2 1 0.5)")
        text = re.sub(r"(frontAndBack\s*\{\s*type\s+)empty;", r"\1wall;", text)
        with open(mesh_dict, "w") as f:
            f.write(text)
        r = run(["blockMesh"], cwd=case)
        self.assertEqual(r.returncode, 0, r.stdout[-2000:])
        motion = self.motion({"radius": 0.05, "patches": {"movingWall": {"translate": [0, -0.002, 0]},
                                                          "fixedWalls": "fixed", "frontAndBack": "fixed"}})
        out = case + "-morphed"
        r = morph(case, out, motion)
        self.assertEqual(r.returncode, 0, r.stderr)
        report = json.loads(r.stdout)
        self.assertEqual(report["cells"], 960)
        self.assert_determinant_matches(report, out)
        before, after = report["quality"]["before"]["polyhedra"], report["quality"]["after"]["polyhedra"]
        self.assertNotEqual(before["mean_determinant"], after["mean_determinant"])

    def test_a_motion_without_a_radius_chooses_one_and_says_why(self):
        case = os.path.join(SOURCE, "examples", "airfoil", "case")
        rotate = {"airfoil": {"rotate": {"axis": [0, 0, 1], "degrees": -5, "origin": [0.25, 0, 0]}}, "farfield": "fixed"}
        reports = []
        for i, (motion, extra) in enumerate((({"patches": rotate}, []), ({"radius": "auto", "patches": rotate}, []),
                                             ({"radius": 4, "patches": rotate}, ["--radius", "auto"]))):
            out = os.path.join(self.tmp, "auto%d" % i)
            r = morph(case, out, self.motion(motion), *extra)
            self.assertEqual(r.returncode, 0, r.stderr)
            reports.append(json.loads(r.stdout))
            self.assertTrue(check_mesh(out)["ok"])
        for report in reports:
            # 20 x the trailing edge's displacement (0.75 x sin 5 degrees, as a chord).
            self.assertAlmostEqual(report["radius"], 20 * report["max_displacement"], delta=1e-12)
            self.assertIn("20 x the largest displacement", report["radius_why"])
            self.assertEqual(report["reach"], 2 * report["radius"])
            self.assertGreater(report["predicted"]["neighbours_per_control"], 10)
        # The text report says it too; a radius given is "given".
        r = run([CLI, "morph", case, "-o", os.path.join(self.tmp, "text"), "--motion", self.motion({"patches": rotate})])
        self.assertIn("(auto: 20 x the largest displacement", r.stdout)
        r = morph(case, os.path.join(self.tmp, "given"), self.motion({"radius": 4, "patches": rotate}))
        self.assertEqual(json.loads(r.stdout)["radius_why"], "given")
        r = morph(case, os.path.join(self.tmp, "bad"), self.motion({"patches": rotate}), "--radius", "huge")
        self.assertEqual(r.returncode, 2)
        self.assertIn("--radius", r.stderr)

    def test_progress_shows_on_a_terminal_only(self):
        # A 3-D cavity of 68 921 points whose lid moves: its fit at R = 0.02 has ~1000 neighbours a control.
        case = os.path.join(self.tmp, "cavity")
        shutil.copytree(os.path.join(os.path.dirname(TUTORIALS), "..", "incompressible", "icoFoam", "cavity", "cavity"),
                        case)
        mesh_dict = os.path.join(case, "system", "blockMeshDict")
        text = read_text(mesh_dict).decode().replace("(20 20 1) simpleGrading", "(40 40 40) simpleGrading")
        with open(mesh_dict, "w") as f:
            f.write(re.sub(r"(frontAndBack\s*\{\s*type\s+)empty;", r"\1wall;", text))
        self.assertEqual(run(["blockMesh"], cwd=case).returncode, 0)
        motion = self.motion({"radius": 0.02, "patches": {"movingWall": {"translate": [0, -0.0003, 0]},
                                                          "fixedWalls": "fixed", "frontAndBack": "fixed"}})

        def on_terminal(out, *extra):
            """(status, standard output, what a terminal on standard error showed)"""
            import pty
            master, slave = pty.openpty()
            p = subprocess.Popen([CLI, "morph", case, "-o", out, "--motion", motion, "--json", *extra],
                                 stdout=subprocess.PIPE, stderr=slave, env=dict(ENV, CSRBF_PROGRESS_DELAY_MS="0"))
            os.close(slave)
            shown = b""
            while True:
                try:
                    chunk = os.read(master, 65536)
                except OSError:  # the child closed the terminal
                    break
                if not chunk:
                    break
                shown += chunk
            os.close(master)
            stdout, _ = p.communicate(timeout=600)
            return p.returncode, stdout.decode(), shown.decode()

        code, stdout, shown = on_terminal(os.path.join(self.tmp, "shown"))
        self.assertEqual(code, 0, shown)
        report = json.loads(stdout)  # the report is whole: nothing of the progress in it
        self.assertTrue(report["written"])
        self.assertIn("csrbf: predicted: ", shown)
        self.assertIn("neighbours each", shown)
        # A bar with its fraction and the time left, for the fit at least; each drawn over the last
        # (carriage return, erase line) and erased when its phase ends.
        bars = re.findall(r"\r\x1b\[K  (\S+(?: \S+)?)\s+\[([#.]{30})\]\s+(\d+)%  [^\r]*", shown)
        self.assertIn("fit", {b[0] for b in bars}, shown)
        self.assertTrue(shown.endswith("\r\x1b[K"), repr(shown[-200:]))
        # --quiet, or standard error not a terminal: nothing.
        code, stdout, shown = on_terminal(os.path.join(self.tmp, "quiet"), "--quiet")
        self.assertEqual((code, shown), (0, ""))
        self.assertEqual(json.loads(stdout)["radius"], 0.02)
        r = run([CLI, "morph", case, "-o", os.path.join(self.tmp, "piped"), "--motion", motion])
        self.assertEqual((r.returncode, r.stderr), (0, ""))

    def test_a_motion_series_writes_each_time_from_one_factorisation(self):
        source = os.path.join(SOURCE, "examples", "airfoil", "case")
        series = os.path.join(self.tmp, "series")
        os.makedirs(series)

        def pitch(degrees):
            return {"patches": {"airfoil": {"rotate": {"axis": [0, 0, 1], "degrees": degrees, "origin": [0.25, 0, 0]}},
                                "farfield": "fixed"}}
        times = {"0.001": -1, "0.002": -2.5, "0.0035": -4}
        for t, d in times.items():
            with open(os.path.join(series, t + ".json"), "w") as f:
                json.dump(pitch(d), f)
        out = os.path.join(self.tmp, "out")
        r = run([CLI, "morph", source, "-o", out, "--motion-series", series, "--json"])
        self.assertEqual(r.returncode, 0, r.stderr)
        report = json.loads(r.stdout)
        self.assertTrue(report["written"])
        self.assertEqual([s["time"] for s in report["steps"]], ["0.001", "0.002", "0.0035"])
        # Auto's R from the series' largest displacement: one R, one factorisation, two solves.
        radii = {s["radius"] for s in report["steps"]}
        self.assertEqual(len(radii), 1)
        self.assertAlmostEqual(radii.pop(), 20 * report["steps"][-1]["max_displacement"], delta=1e-12)
        self.assertEqual((report["factorisations"], report["solves_reused"]), (1, 2))
        self.assertEqual([s["reused_factorisation"] for s in report["steps"]], [False, True, True])
        # Each time's points equal a morph of that motion alone; constant/ is the input's.
        self.assertEqual(read_text(os.path.join(out, "constant/polyMesh/points")),
                         read_text(os.path.join(source, "constant/polyMesh/points")))
        for t, d in times.items():
            single = os.path.join(self.tmp, "single" + t)
            r = morph(source, single, self.motion(pitch(d)), "--radius", repr(report["steps"][0]["radius"]))
            self.assertEqual(r.returncode, 0, r.stderr)
            want = [list(map(float, l.strip("()").split())) for l in
                    read_text(os.path.join(single, "constant/polyMesh/points")).decode().split("\n") if l.startswith("(")
                    and l.count(" ") == 2]
            got = [list(map(float, l.strip("()").split())) for l in
                   read_text(os.path.join(out, t, "polyMesh/points")).decode().split("\n") if l.startswith("(")
                   and l.count(" ") == 2]
            self.assertEqual(len(got), 7872)
            self.assertLess(max(abs(a - b) for p, q in zip(got, want) for a, b in zip(p, q)), 1e-12)
            cm = run(["checkMesh", "-time", t], cwd=out)
            self.assertIn("Mesh OK.", cm.stdout, cm.stdout[-2000:])
        # In place: a copy of the case gets its time folders; a series whose last step inverts cells
        # writes no time at all and leaves no folder behind.
        case = os.path.join(self.tmp, "case")
        shutil.copytree(source, case)
        with open(os.path.join(series, "0.005.json"), "w") as f:
            json.dump({"radius": 0.3, "patches": {"airfoil": {"translate": [0, 0.5, 0]}, "farfield": "fixed"}}, f)
        # What the attacker found: a link planted where an older csrbf staged its points (a fixed
        # name) is neither written through nor removed; an existing time folder without a polyMesh
        # is left as it was.
        victim = os.path.join(self.tmp, "victim.txt")
        with open(victim, "w") as f:
            f.write("mine")
        os.makedirs(os.path.join(case, "0.002", "polyMesh"))
        planted = os.path.join(case, "0.002", "polyMesh", ".csrbf-new-points")
        os.symlink(victim, planted)
        os.makedirs(os.path.join(case, "0.001"))
        r = run([CLI, "morph", case, "--in-place", "--motion-series", series])
        self.assertEqual(r.returncode, 1, r.stdout)
        self.assertIn("time 0.005", r.stderr)
        self.assertIn("no time written", r.stderr)
        with open(victim) as f:
            self.assertEqual(f.read(), "mine")
        self.assertTrue(os.path.islink(planted))
        self.assertEqual(os.listdir(os.path.join(case, "0.001")), [])
        self.assertEqual(os.listdir(os.path.join(case, "0.002", "polyMesh")), [".csrbf-new-points"])
        shutil.rmtree(os.path.join(case, "0.001"))
        shutil.rmtree(os.path.join(case, "0.002"))
        self.assertEqual(sorted(os.listdir(case)), sorted(os.listdir(source)))
        # -o inside the case is refused before anything is copied.
        r = run([CLI, "morph", case, "-o", os.path.join(case, "out"), "--motion-series", series])
        self.assertEqual(r.returncode, 1)
        self.assertIn("it is inside the case", r.stderr)
        os.remove(os.path.join(series, "0.005.json"))
        r = run([CLI, "morph", case, "--in-place", "--motion-series", series])
        self.assertEqual(r.returncode, 0, r.stderr)
        for t in times:
            self.assertEqual(read_text(os.path.join(case, t, "polyMesh/points")),
                             read_text(os.path.join(out, t, "polyMesh/points")))
        # Refused: a file not named by a time, a mesh file, --motion beside it, under a time already passed.
        with open(os.path.join(series, "final.json"), "w") as f:
            json.dump(pitch(-1), f)
        r = run([CLI, "morph", source, "-o", os.path.join(self.tmp, "x"), "--motion-series", series])
        self.assertEqual(r.returncode, 1)
        self.assertIn("'final.json' is not named by a time", r.stderr)
        os.remove(os.path.join(series, "final.json"))
        r = run([CLI, "morph", source, "-o", os.path.join(self.tmp, "x"), "--motion-series", series, "--motion",
                 os.path.join(series, "0.001.json")])
        self.assertEqual(r.returncode, 2)
        r = run([CLI, "morph", case, "-o", os.path.join(self.tmp, "x"), "--motion-series", series, "-time", "0.002"])
        self.assertEqual(r.returncode, 1)
        self.assertIn("time 0.001 is not after the time read, 0.002", r.stderr)
        self.assertFalse(os.path.exists(os.path.join(self.tmp, "x")))

    def test_a_solver_on_the_morphed_square_bend_follows_the_original(self):
        # Issue 31, point 10: rhoSimpleFoam's squareBend (112 000 cells) with a 2.5 mm bump pushed
        # into its outer bend wall, R = 25 mm, no greedy: 30 iterations on the original and on the
        # morphed mesh; from iteration 10 on, every field's initial residual stays within 3x of the
        # original's (1.08x when this was written), and the points 2R from the bump keep their bits.
        src = os.path.join(os.path.dirname(TUTORIALS), "..", "compressible", "rhoSimpleFoam", "squareBend")
        case = os.path.join(self.tmp, "squareBend")
        shutil.copytree(src, case)
        control = os.path.join(case, "system", "controlDict")
        text = read_text(control).decode()
        text = re.sub(r"\nendTime\s+\S+;", "\nendTime 30;", text)
        text = re.sub(r"\nwriteInterval\s+\S+;", "\nwriteInterval 1000;", text)
        with open(control, "w") as f:
            f.write(text)
        self.assertEqual(run(["blockMesh"], cwd=case).returncode, 0)
        poly = os.path.join(case, "constant", "polyMesh")
        body = lambda name: read_text(os.path.join(poly, name)).decode().split("\n(", 1)[1]
        pts = [tuple(map(float, m)) for m in re.findall(r"\(([-\d.e+]+) ([-\d.e+]+) ([-\d.e+]+)\)", body("points"))]
        self.assertEqual(len(pts), 123921)
        faces = [list(map(int, f.split())) for f in re.findall(r"\d+\(([\d ]+)\)", body("faces"))]
        walls = re.search(r"walls\s*\{[^}]*?nFaces\s+(\d+);\s*startFace\s+(\d+);", read_text(os.path.join(poly, "boundary")).decode())
        count, start = int(walls.group(1)), int(walls.group(2))
        ids = sorted({v for f in faces[start:start + count] for v in f})
        moving = []
        with open(os.path.join(self.tmp, "bump.txt"), "w") as f:
            for v in ids:
                x, y, z = pts[v]
                r, th = math.hypot(x, y), math.degrees(math.atan2(y, x))
                d = (0.0, 0.0)
                if x > 0 and abs(r - 0.075) < 1e-6 and abs(th) < 30 and abs(z) < 0.02:
                    a = -0.0025 * math.cos(math.pi * th / 60) ** 2 * math.cos(math.pi * z / 0.04) ** 2
                    d = (a * x / r, a * y / r)
                    moving.append(pts[v])
                f.write("%d %.17g %.17g 0\n" % (v, d[0], d[1]))
        motion = os.path.join(self.tmp, "motion.json")
        with open(motion, "w") as f:
            json.dump({"radius": 0.025, "patches": {"walls": {"displacements": "bump.txt"}, "inlet": "fixed",
                                                    "outlet": "fixed"}}, f)
        out = os.path.join(self.tmp, "morphed")
        r = morph(case, out, motion)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(json.loads(r.stdout)["reach"], 0.05)
        new = [tuple(map(float, m)) for m in re.findall(r"\(([-\d.e+]+) ([-\d.e+]+) ([-\d.e+]+)\)",
                                                       read_text(os.path.join(out, "constant/polyMesh/points")).decode().split("\n(", 1)[1])]
        import numpy as np
        old_p, new_p, bump = np.array(pts), np.array(new), np.array(moving)
        gap = np.full(len(old_p), np.inf)
        for b in bump:
            gap = np.minimum(gap, np.linalg.norm(old_p - b, axis=1))
        far = gap >= 0.05
        self.assertGreater(far.sum(), 100000)
        self.assertTrue(np.array_equal(old_p[far], new_p[far]))
        self.assertGreater(np.abs(new_p - old_p).max(), 0.002)

        def residuals(folder):
            log = run(["rhoSimpleFoam"], cwd=folder)
            self.assertEqual(log.returncode, 0, log.stdout[-3000:])
            it, res = 0, {}
            for line in log.stdout.split("\n"):
                if line.startswith("Time ="):
                    it = int(float(line.split("=")[1]))
                m = re.search(r"Solving for (\w+), Initial residual = (\S+),", line)
                if m and it:
                    res.setdefault(m.group(1), {}).setdefault(it, float(m.group(2)))
            return res

        a, b = residuals(case), residuals(out)
        self.assertEqual(sorted(a), ["Ux", "Uy", "Uz", "e", "epsilon", "k", "p"])
        for field in a:
            self.assertEqual(len(a[field]), 30, field)
            for i in range(10, 31):
                ratio = b[field][i] / a[field][i]
                self.assertLess(max(ratio, 1 / ratio), 3.0, (field, i, a[field][i], b[field][i]))

    def test_a_gzipped_case_is_written_in_parallel_blocks_any_reader_takes(self):
        # 68 921 points, 1.8 MB of ASCII: two blocks deflated apart, one gzip member. Python's gzip,
        # csrbf's own reader and checkMesh read it; its text is the plain case's byte for byte.
        cases = {}
        for gz in (False, True):
            case = os.path.join(self.tmp, "cavity-gz" if gz else "cavity")
            shutil.copytree(os.path.join(os.path.dirname(TUTORIALS), "..", "incompressible", "icoFoam", "cavity",
                                         "cavity"), case)
            mesh_dict = os.path.join(case, "system", "blockMeshDict")
            text = read_text(mesh_dict).decode().replace("(20 20 1) simpleGrading", "(40 40 40) simpleGrading")
            with open(mesh_dict, "w") as f:
                f.write(re.sub(r"(frontAndBack\s*\{\s*type\s+)empty;", r"\1wall;", text))
            self.assertEqual(run(["blockMesh"], cwd=case).returncode, 0)
            if gz:
                subprocess.run(["gzip", os.path.join(case, "constant", "polyMesh", "points")], check=True)
            cases[gz] = case
        motion = self.motion({"radius": 0.02, "patches": {"movingWall": {"translate": [0, -0.0003, 0]},
                                                          "fixedWalls": "fixed", "frontAndBack": "fixed"}})
        outs = {}
        for gz, case in cases.items():
            out = case + "-morphed"
            r = morph(case, out, motion)
            self.assertEqual(r.returncode, 0, r.stderr)
            outs[gz] = out
        written = os.path.join(outs[True], "constant", "polyMesh", "points.gz")
        with open(written, "rb") as f:
            raw = f.read()
        self.assertEqual(raw[:3], b"\x1f\x8b\x08")
        self.assertGreater(len(gzip.decompress(raw)), 1 << 20)  # two blocks at least
        self.assertEqual(gzip.decompress(raw), read_text(os.path.join(outs[False], "constant", "polyMesh", "points")))
        self.assertTrue(check_mesh(outs[True])["ok"])
        # csrbf reads its own output back: a second morph of it by nothing moves nothing.
        again = morph(outs[True], outs[True] + "-again", motion, "--phase", "0")
        self.assertEqual(again.returncode, 0, again.stderr)

    def test_bad_input_is_refused_with_nothing_written(self):
        case = os.path.join(SOURCE, "examples", "airfoil", "case")
        out = os.path.join(self.tmp, "out")
        cases = [
            ({"radius": 4, "patches": {"wing": "fixed"}}, 1, "no patch 'wing'; its patches: airfoil, farfield, frontAndBack"),
            ({"radius": "big", "patches": {"airfoil": "fixed"}}, 1, 'radius: expected a number > 0 or "auto"'),
            ({"radius": 4, "patches": {"airfoil": {"rotate": {"axis": [0, 0, 0], "degrees": 5}}}}, 1,
             "patches.airfoil.rotate.axis"),
            ({"radius": 4, "patches": {"airfoil": {"translate": [0, 0.1, 0]}, "frontAndBack": {"translate": [0, 0, 0.1]}}},
             1, "give the two patches the same motion"),
        ]
        for motion, code, text in cases:
            r = morph(case, out, self.motion(motion))
            self.assertEqual(r.returncode, code, (motion, r.stdout, r.stderr))
            self.assertIn(text, r.stderr)
            self.assertFalse(os.path.exists(out))
        good = os.path.join(SOURCE, "examples", "airfoil", "motion.json")
        r = run([CLI, "morph", case, "--motion", good])
        self.assertEqual(r.returncode, 2)
        self.assertIn("-o OUT", r.stderr)
        r = run([CLI, "morph", case, "-o", out, "--in-place", "--motion", good])
        self.assertEqual(r.returncode, 2)
        os.makedirs(out)
        r = run([CLI, "morph", case, "-o", out, "--motion", good])
        self.assertEqual(r.returncode, 1)
        self.assertIn("it exists", r.stderr)
        self.assertEqual(os.listdir(out), [])
        # A truncated points file, a count that disagrees with faces.
        broken = os.path.join(self.tmp, "broken")
        shutil.copytree(case, broken)
        points = os.path.join(broken, "constant", "polyMesh", "points")
        text = read_text(points)
        with open(points, "wb") as f:
            f.write(text[: len(text) // 2])
        r = morph(broken, os.path.join(self.tmp, "o2"), good)
        self.assertEqual(r.returncode, 1)
        self.assertIn("points", r.stderr)
        with open(points, "wb") as f:
            f.write(text.replace(b"7872\n(", b"7000\n(", 1))
        r = morph(broken, os.path.join(self.tmp, "o3"), good)
        self.assertEqual(r.returncode, 1)
        self.assertIn("more points than the count", r.stderr)
        self.assertFalse(os.path.exists(os.path.join(self.tmp, "o2")))
        self.assertFalse(os.path.exists(os.path.join(self.tmp, "o3")))


if __name__ == "__main__":
    unittest.main()
