"""The Python module against the C++ command line (bit for bit), SciPy, and its error messages.

Run by CTest with Debian's /usr/bin/python3; PYTHONPATH points at the built module, CSRBF_CLI at the
csrbf program and CSRBF_SOURCE_DIR at the repository.
"""
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import unittest

import numpy as np
import scipy.sparse
import scipy.sparse.linalg
import scipy.spatial

import csrbf

CLI = os.environ["CSRBF_CLI"]
EXAMPLES = os.path.join(os.environ["CSRBF_SOURCE_DIR"], "examples")


def obj_vertices(path):
    with open(path) as f:
        return np.array([[float(t) for t in line.split()[1:4]] for line in f if line.startswith("v ")])


def wendland_c2(r):
    return np.where(r < 1, (1 - r) ** 4 * (4 * r + 1), 0.0)


def csrbf_matrix(s, radius):
    """The CSRBF matrix A of points s (Wendland C2), built by SciPy: cKDTree pairs, a sparse matrix."""
    n = len(s)
    pairs = scipy.spatial.cKDTree(s).query_pairs(radius, output_type="ndarray")
    r = np.linalg.norm(s[pairs[:, 0]] - s[pairs[:, 1]], axis=1) / radius
    rows = np.concatenate([pairs[:, 0], pairs[:, 1], np.arange(n)])
    cols = np.concatenate([pairs[:, 1], pairs[:, 0], np.arange(n)])
    vals = np.concatenate([wendland_c2(r), wendland_c2(r), np.ones(n)])
    return scipy.sparse.csc_matrix((vals, (rows, cols)), shape=(n, n))


class SameAsTheCommandLine(unittest.TestCase):
    def test_deform_fish_bit_for_bit(self):
        sources, destinations = csrbf.read_controls(os.path.join(EXAMPLES, "fish.controls"))
        self.assertEqual(sources.shape, (92, 3))
        rest, faces = csrbf.read_mesh(os.path.join(EXAMPLES, "fish.obj"))
        self.assertEqual(rest.shape, (977, 3))
        self.assertEqual(len(faces), 1000)
        for kernel, polynomial, phase in (("c2", "none", 1.0), ("c4", "linear", 0.5)):
            with tempfile.TemporaryDirectory() as tmp:
                out = os.path.join(tmp, "out.obj")
                subprocess.run([CLI, "deform", "--mesh", os.path.join(EXAMPLES, "fish.obj"), "--controls",
                                os.path.join(EXAMPLES, "fish.controls"), "--radius", "0.3", "--kernel", kernel,
                                "--polynomial", polynomial, "--phase", str(phase), "-o", out],
                               check=True, capture_output=True)
                cli = obj_vertices(out)
            m = csrbf.SpaceMap(sources, destinations, 0.3, kernel=kernel, polynomial=polynomial)
            py = m(rest, phase=phase)
            # The CLI writes the shortest text that reads back as the same double.
            np.testing.assert_array_equal(py, cli)

    def test_one_version(self):
        # Both come from project(csrbf VERSION ...) through csrbf/version.hpp.
        out = subprocess.run([CLI, "--version"], check=True, capture_output=True, text=True).stdout.strip()
        self.assertEqual(out, "csrbf " + csrbf.__version__)
        self.assertRegex(csrbf.__version__, r"^\d+\.\d+\.\d+$")

    def test_import_loads_the_file_libraries_on_first_use(self):
        # `import csrbf` is the core alone; the file functions' extension (csrbf._io, with VTK, assimp
        # and CGNS) is loaded by the first use of one of its names, and then stays.
        code = """
import sys, csrbf
maps = lambda: open("/proc/self/maps").read()
assert "csrbf._io" not in sys.modules and "libvtk" not in maps() and "libassimp" not in maps(), maps()
assert "read_mesh" in dir(csrbf) and "Scene" in dir(csrbf)
read = csrbf.read_mesh
assert "csrbf._io" in sys.modules and "libvtk" in maps()
assert csrbf.read_mesh is read and csrbf.FileError.__module__ == "csrbf" and issubclass(csrbf.FileError, OSError)
assert read.__module__ == "csrbf" and csrbf.Scene.__module__ == "csrbf", (read.__module__, csrbf.Scene.__module__)
try:
    csrbf.not_a_name
except AttributeError as e:
    assert "module 'csrbf' has no attribute 'not_a_name'" in str(e), e
else:
    raise AssertionError("no AttributeError")
"""
        r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
        self.assertEqual(r.returncode, 0, r.stderr)
        # `from csrbf import *` brings the file functions (csrbf.__all__ names them).
        code = "from csrbf import *\nassert callable(read_mesh) and issubclass(FileError, OSError) and Interpolator"
        r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
        self.assertEqual(r.returncode, 0, r.stderr)
        # Where the file extension cannot be loaded, its names are missing attributes that say why;
        # the rest of csrbf works.
        code = """
import sys
sys.modules["csrbf._io"] = None
import csrbf, numpy as np
assert not hasattr(csrbf, "read_mesh")
try:
    csrbf.read_mesh
except AttributeError as e:
    assert "csrbf.read_mesh is in csrbf's file extension csrbf._io, which could not be loaded" in str(e), e
assert csrbf.Interpolator(np.eye(3)[:, :2], np.ones(3), radius=2.0)(np.zeros(2)) > 0
"""
        r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
        self.assertEqual(r.returncode, 0, r.stderr)

    def test_deformation_file_round_trip(self):
        s, d = csrbf.read_controls(os.path.join(EXAMPLES, "face.controls"))
        m = csrbf.SpaceMap(s, d, 0.2, kernel="c6")
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "face.json")
            csrbf.write_deformation(path, m)
            back = csrbf.read_deformation(path)
        self.assertEqual(back.kernel, "c6")
        self.assertEqual(back.radius, 0.2)
        np.testing.assert_array_equal(back.sources, m.sources)
        x = np.random.default_rng(0).random((100, 3))
        np.testing.assert_array_equal(back(x), m(x))


    def test_active_area_as_the_command_line(self):
        # A deformation file with an active area (the Picker's ctrl + drag): apply_deformation moves
        # exactly the vertices `csrbf deform --deformation` moves, bit for bit; the others stay.
        rest, faces = csrbf.read_mesh(os.path.join(EXAMPLES, "fish.obj"))
        area = [int(i) for i in np.flatnonzero(rest[:, 0] > 0.62)]
        sources, destinations = csrbf.read_controls(os.path.join(EXAMPLES, "fish.controls"))
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "tail.json")
            with open(path, "w") as f:
                json.dump({"format": "csrbf-deformation", "version": 1, "kernel": "c2", "radius": 0.3,
                           "polynomial": "none", "sources": sources.tolist(), "destinations": destinations.tolist(),
                           "active_area": {"vertex_count": len(rest), "vertices": area}}, f)
            np.testing.assert_array_equal(csrbf.read_active_area(path), area)
            py = csrbf.apply_deformation(path, rest, phase=0.75)
            out = os.path.join(tmp, "out.obj")
            subprocess.run([CLI, "deform", "--mesh", os.path.join(EXAMPLES, "fish.obj"), "--deformation", path,
                            "--phase", "0.75", "-o", out], check=True, capture_output=True)
            np.testing.assert_array_equal(py, obj_vertices(out))
            outside = np.setdiff1d(np.arange(len(rest)), area)
            np.testing.assert_array_equal(py[outside], rest[outside])
            self.assertGreater(np.abs(py[area] - rest[area]).max(), 0.01)
            with self.assertRaisesRegex(csrbf.FileError, "picked on a mesh of 977 vertices, positions has 976"):
                csrbf.apply_deformation(path, rest[:-1])
            whole = os.path.join(tmp, "whole.json")
            csrbf.write_deformation(whole, csrbf.SpaceMap(sources, destinations, 0.3))
            self.assertIsNone(csrbf.read_active_area(whole))


class AgainstScipy(unittest.TestCase):
    def test_estimate_and_suggest_radius_before_a_fit(self):
        # Issue 32: cost before work. The neighbours the estimate counts are the fit's.
        rng = np.random.default_rng(7)
        s = rng.random((3000, 3))
        r = csrbf.suggest_radius(s, 20)
        e = csrbf.estimate(s, r)
        self.assertTrue(e["exact"])
        self.assertAlmostEqual(e["mean_neighbors"], 20, delta=2)
        self.assertEqual([x["solver"] for x in e["solvers"]][0], "envelope")
        m = csrbf.SpaceMap(s, s + 0.01, r)
        self.assertEqual(m.stats["mean_neighbors"], e["mean_neighbors"])
        self.assertTrue(all(x["seconds"] > 0 and x["bytes"] > 0 for x in e["solvers"]))
        with self.assertRaisesRegex(ValueError, "neighbours must be within"):
            csrbf.suggest_radius(s, 5000)

    def test_same_interpolation_problem_solved_by_scipy(self):
        # SciPy's RBFInterpolator has no compactly supported kernel, so the same problem (Wendland
        # C2, no polynomial) is built with cKDTree neighbours and solved by scipy.sparse's spsolve.
        rng = np.random.default_rng(42)
        n, radius = 400, 0.25
        s = rng.random((n, 3))
        g = 0.05 * rng.standard_normal((n, 3))
        tree = scipy.spatial.cKDTree(s)
        alpha = scipy.sparse.linalg.spsolve(csrbf_matrix(s, radius), g)
        m = csrbf.SpaceMap(s, s + g, radius)
        np.testing.assert_allclose(m.coefficients, alpha, rtol=0, atol=1e-9)
        # The interpolant at random points, evaluated by SciPy from alpha.
        x = rng.random((500, 3))
        near = tree.query_ball_point(x, radius)
        expect = np.zeros_like(x)
        for i, js in enumerate(near):
            js = np.array(js, dtype=int)
            if js.size:
                w = wendland_c2(np.linalg.norm(s[js] - x[i], axis=1) / radius)
                expect[i] = w @ alpha[js]
        np.testing.assert_allclose(m.displacement(x), expect, rtol=0, atol=1e-9)
        np.testing.assert_allclose(m(x), x + expect, rtol=0, atol=1e-9)


    def test_every_solver_and_new_destinations(self):
        # Each back end solves the same system as scipy.sparse's spsolve; with_destinations re-solves
        # (CG from the previous solution) and equals a fresh fit; the memory limit raises MemoryError.
        rng = np.random.default_rng(43)
        n, radius = 1500, 0.12
        s = rng.random((n, 3))
        g = 0.02 * rng.standard_normal((n, 3))
        a = csrbf_matrix(s, radius)
        alpha = scipy.sparse.linalg.spsolve(a, g)
        for solver in ["auto", "envelope", "eigen", "cholmod", "cg"]:
            ordering = "auto" if solver in ("eigen", "cholmod") else "rcm"
            m = csrbf.SpaceMap(s, s + g, radius, solver=solver, ordering=ordering)
            np.testing.assert_allclose(m.coefficients, alpha, rtol=0, atol=1e-8 * np.abs(alpha).max(), err_msg=solver)
        cg = csrbf.SpaceMap(s, s + g, radius, solver="cg")
        self.assertEqual(cg.stats["solver"], "cg")
        g2 = g.copy()
        g2[::100] += 0.001
        moved = cg.with_destinations(s + g2)
        self.assertTrue(moved.stats["warm_start"])
        self.assertLess(moved.stats["iterations"], cg.stats["iterations"])
        alpha2 = scipy.sparse.linalg.spsolve(a, g2)
        np.testing.assert_allclose(moved.coefficients, alpha2, rtol=0, atol=1e-8 * np.abs(alpha2).max())
        np.testing.assert_array_equal(cg.coefficients, csrbf.SpaceMap(s, s + g, radius, solver="cg").coefficients)
        with self.assertRaisesRegex(ValueError, "1500 sources but 10 destinations"):
            cg.with_destinations(s[:10])
        with self.assertRaisesRegex(ValueError, "destinations"):
            cg.with_destinations(np.full((n, 3), np.nan))
        with self.assertRaisesRegex(ValueError, "solver must be one of 'auto', 'envelope', 'eigen', 'cholmod' or 'cg'"):
            csrbf.SpaceMap(s, s + g, radius, solver="lu")
        with self.assertRaisesRegex(ValueError, "solver 'cholmod' orders the matrix itself"):
            csrbf.SpaceMap(s, s + g, radius, solver="CHOLMOD", ordering="rcm")
        with self.assertRaisesRegex(MemoryError, "above the limit"):
            csrbf.SpaceMap(s, s + g, 0.9, memory_limit=1e6 / 2**30)
        # A list numpy cannot make an array of: its type, length and first bad element, not the whole list
        # (issue 30: pybind11 printed every element).
        ragged = [[0.0, 0.0, 0.0]] * 5000 + [[1.0, 2.0]] + [[0.0, 0.0, 0.0]] * 5000
        with self.assertRaises(TypeError) as caught:
            csrbf.SpaceMap(ragged, ragged, radius)
        message = str(caught.exception)
        self.assertIn("sources must be an array of shape (n, 3) of numbers, got a list of 10001 elements; "
                      "element [5000] is [1.0, 2.0] (list)", message)
        self.assertLess(len(message), 300, message)
        # GiB, as the command line takes it (issue 30: it was bytes here, GiB in csrbf.morph).
        with self.assertRaisesRegex(ValueError, r"memory_limit is in GiB, as csrbf's --memory-limit: .* got 1e\+09 \(bytes\? 0.931"):
            csrbf.SpaceMap(s, s + g, radius, memory_limit=1e9)


class Arrays(unittest.TestCase):
    def setUp(self):
        rng = np.random.default_rng(7)
        self.s = rng.random((60, 3))
        self.m = csrbf.SpaceMap(self.s, self.s + [0.0, 0.0, 0.02], 0.3)

    def test_float32_in_float32_out(self):
        x = np.random.default_rng(1).random((1000, 3))
        y64 = self.m(x)
        y32 = self.m(x.astype(np.float32))
        self.assertEqual(y32.dtype, np.float32)
        self.assertEqual(y64.dtype, np.float64)
        np.testing.assert_allclose(y32, y64, atol=1e-5)
        # Other layouts are accepted (converted): Fortran order, integers, a transposed view.
        np.testing.assert_array_equal(self.m(np.asfortranarray(x)), y64)
        np.testing.assert_array_equal(self.m(x.T.copy().T), y64)
        self.assertEqual(self.m(np.zeros((2, 3), dtype=np.int64)).dtype, np.float64)

    def test_any_order_and_out(self):
        # 50 000 points in lattice order and shuffled (the shuffled batch is gathered by cell inside):
        # the same results in the caller's order; `out=` receives them, the input itself allowed.
        g = np.linspace(-0.2, 1.2, 37)
        x = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
        perm = np.random.default_rng(5).permutation(len(x))
        y = self.m(x, phase=0.6)
        ys = self.m(x[perm], phase=0.6)
        np.testing.assert_allclose(ys, y[perm], rtol=0, atol=1e-14)
        out = np.empty_like(x)
        self.assertIs(self.m(x[perm], phase=0.6, out=out), out)
        np.testing.assert_array_equal(out, ys)
        inplace = x[perm].copy()
        self.m(inplace, phase=0.6, out=inplace)
        np.testing.assert_array_equal(inplace, ys)
        d = np.empty_like(x)
        self.m.displacement(x, out=d)
        np.testing.assert_allclose(x + 0.6 * d, y, rtol=0, atol=1e-14)
        f = x.astype(np.float32)
        outf = np.empty_like(f)
        self.m(f, out=outf)
        np.testing.assert_allclose(outf, self.m(x), atol=1e-5)
        # An out that overlaps the points without being them: the result as if they were apart.
        buf = np.zeros(3 * (len(x) + 1))
        pts = buf[:3 * len(x)].reshape(-1, 3)
        pts[:] = x[perm]
        shifted = buf[3:].reshape(-1, 3)
        self.m(pts, phase=0.6, out=shifted)
        np.testing.assert_array_equal(shifted, ys)
        pts[:] = x[perm]
        src = buf[3:].reshape(-1, 3)  # the same memory, one row on
        expected = self.m.displacement(src.copy())
        self.m.displacement(src, out=pts)
        np.testing.assert_array_equal(pts, expected)
        # A wrong out is refused by name, before anything is written.
        for bad, why in ((np.empty((len(x), 3), dtype=np.float32), "float64"), (np.empty((len(x), 2)), "3"),
                         (np.empty((3, len(x))).T, "C-contiguous"), ([0.0] * 3, "numpy array")):
            with self.assertRaisesRegex((ValueError, TypeError), why):
                self.m(x, out=bad)
        ro = np.empty_like(x)
        ro.setflags(write=False)
        with self.assertRaisesRegex(ValueError, "writeable"):
            self.m(x, out=ro)
        # A NaN anywhere is named by row and column, whichever thread finds it.
        xn = x.copy()
        xn[31337, 2] = np.nan
        xn[40000, 0] = np.inf
        with self.assertRaisesRegex(ValueError, r"points\[31337, 2\] is nan"):
            self.m(xn)

    def test_jacobian_and_field(self):
        x = np.random.default_rng(3).random((20, 3))
        j = self.m.jacobian(x, phase=0.5)
        h = 1e-6
        for b in range(3):
            e = np.zeros(3)
            e[b] = h
            fd = (self.m(x + e, phase=0.5) - self.m(x - e, phase=0.5)) / (2 * h)
            np.testing.assert_allclose(j[:, :, b], fd, atol=1e-7)
        field = csrbf.DisplacementField(self.m, x)
        np.testing.assert_allclose(field(0.25), self.m(x, phase=0.25), atol=1e-15)
        np.testing.assert_allclose(field.displacements, self.m.displacement(x), atol=0)
        stats = self.m.stats
        self.assertEqual(stats["controls"], 60)
        self.assertLess(stats["residual_max"], 1e-12)

    def test_clear_errors(self):
        with self.assertRaisesRegex(ValueError, r"points must have shape \(n, 3\), got \(10, 2\)"):
            self.m(np.zeros((10, 2)))
        with self.assertRaisesRegex(ValueError, r"shape \(n, 3\), got \(3,\)"):
            self.m(np.zeros(3))
        with self.assertRaisesRegex(TypeError, "real numbers"):
            self.m(np.array([["a", "b", "c"]]))
        with self.assertRaisesRegex(ValueError, r"points\[1, 2\] is nan"):
            self.m(np.array([[0, 0, 0], [0, 0, np.nan]], dtype=float))
        with self.assertRaisesRegex(ValueError, r"sources\[0, 0\] is inf"):
            csrbf.SpaceMap(np.array([[np.inf, 0, 0]]), np.zeros((1, 3)), 1.0)
        with self.assertRaisesRegex(ValueError, "kernel must be one of"):
            csrbf.SpaceMap(self.s, self.s, 0.3, kernel="gauss")
        with self.assertRaisesRegex(ValueError, "radius"):
            csrbf.SpaceMap(self.s, self.s, -1.0)
        with self.assertRaisesRegex(ValueError, "sources has 60 points but destinations has 59"):
            csrbf.SpaceMap(self.s, self.s[:-1], 0.3)
        with self.assertRaisesRegex(ValueError, "linear"):
            csrbf.SpaceMap(self.s[:2], self.s[:2], 0.3, polynomial="linear")
        with self.assertRaises(csrbf.FileError):
            csrbf.read_mesh("/nonexistent.obj")
        self.assertTrue(issubclass(csrbf.FileError, OSError))

    def test_hostile_inputs(self):
        # A broadcast view of 2**40 rows needs a 26 TB copy: MemoryError, never a crash.
        huge = np.broadcast_to([0.5, 0.5, 0.5], (2**40, 3))
        for call in (lambda: self.m(huge), lambda: self.m.displacement(huge), lambda: self.m.jacobian(huge),
                     lambda: csrbf.DisplacementField(self.m, huge), lambda: csrbf.SpaceMap(huge, huge, 0.3)):
            with self.assertRaisesRegex(MemoryError, r"cannot make a contiguous copy of \(1099511627776, 3\)"):
                call()
        # Phases: NaN and beyond 1e6 are refused, in every function that takes one.
        x = self.s[:4]
        for bad in (np.nan, 1.7e308, -np.inf):
            with self.assertRaisesRegex(ValueError, "phase must be a finite number"):
                self.m(x, phase=bad)
            with self.assertRaisesRegex(ValueError, "phase must be a finite number"):
                self.m.jacobian(x, phase=bad)
        # (0, 3) arrays give (0, 3) and (0, 3, 3) results alike.
        self.assertEqual(self.m(np.zeros((0, 3))).shape, (0, 3))
        self.assertEqual(self.m.jacobian(np.zeros((0, 3))).shape, (0, 3, 3))
        # pathlib paths are taken wherever a path is.
        import pathlib
        with tempfile.TemporaryDirectory() as d:
            p = pathlib.Path(d)
            csrbf.write_deformation(p / "m.json", self.m)
            again = csrbf.read_deformation(p / "m.json")
            np.testing.assert_allclose(again(x), self.m(x), atol=1e-12)
            pos, faces = csrbf.read_mesh(pathlib.Path(EXAMPLES) / "fish.obj")
            csrbf.write_mesh(pathlib.Path(EXAMPLES) / "fish.obj", pos, p / "f.obj")
            self.assertEqual(csrbf.read_mesh(p / "f.obj")[0].shape, pos.shape)
            s, _ = csrbf.read_controls(pathlib.Path(EXAMPLES) / "fish.controls")
            self.assertEqual(s.shape, (92, 3))
            scene = csrbf.Scene(pathlib.Path(EXAMPLES) / "fish.scene.json")
            self.assertGreater(scene.duration, 0)

    def test_releases_the_gil(self):
        # A Python thread keeps counting while the main thread evaluates a million points.
        big = np.random.default_rng(5).random((1_000_000, 3))
        count = [0]
        stop = threading.Event()

        def counter():
            while not stop.is_set():
                count[0] += 1

        t = threading.Thread(target=counter)
        t.start()
        time.sleep(0.05)
        before = count[0]
        for _ in range(3):
            self.m(big)
        after = count[0]
        stop.set()
        t.join()
        self.assertGreater(after - before, 1000)


class Scenes(unittest.TestCase):
    def test_scene_positions_at_keys(self):
        scene = csrbf.Scene(os.path.join(EXAMPLES, "ball.scene.json"))
        self.assertEqual(scene.objects, ["box", "ball"])
        self.assertEqual(scene.duration, 4.0)
        box, ball = scene.positions(0.5)
        self.assertEqual(box.shape, (386, 3))
        # The ball's centre of gravity follows its second trajectory key at t = 0.5.
        np.testing.assert_allclose(ball.mean(axis=0), [0.85, 0.55, 0.4], atol=1e-3)
        # The box is dented on the right wall, where the ball presses (x > 1).
        self.assertGreater(box[:, 0].max(), 1.0 + 1e-3)
        # Its faces are those of the box's mesh file.
        _, faces = csrbf.read_mesh(os.path.join(EXAMPLES, "box.obj"))
        self.assertEqual(scene.faces(0), faces)


class VtkPython(unittest.TestCase):
    def test_wrapped_transform_in_a_vtk_pipeline(self):
        try:
            import vtk
            from csrbf_vtk import vtkCSRBFTransform
        except ImportError as e:  # a build without VTK's Python wrapping
            self.skipTest(str(e))
        s = np.random.default_rng(9).random((30, 3))
        d = s + [0.0, 0.03, 0.0]
        src, dst = vtk.vtkPoints(), vtk.vtkPoints()
        src.SetDataTypeToDouble()
        dst.SetDataTypeToDouble()
        for p, q in zip(s, d):
            src.InsertNextPoint(*p)
            dst.InsertNextPoint(*q)
        t = vtkCSRBFTransform()
        t.SetSourceLandmarks(src)
        t.SetTargetLandmarks(dst)
        t.SetRadius(0.4)
        t.SetKernel(vtkCSRBFTransform.KERNEL_C4)
        m = csrbf.SpaceMap(s, d, 0.4, kernel="c4")
        x = np.random.default_rng(10).random((20, 3))
        got = np.array([t.TransformPoint(*p) for p in x])
        np.testing.assert_allclose(got, m(x), atol=1e-14)
        back = np.array([t.GetInverse().TransformPoint(*p) for p in got])
        np.testing.assert_allclose(back, x, atol=1e-6)
        sphere = vtk.vtkSphereSource()
        f = vtk.vtkTransformPolyDataFilter()
        f.SetInputConnection(sphere.GetOutputPort())
        f.SetTransform(t)
        f.Update()
        self.assertEqual(f.GetOutput().GetNumberOfPoints(), sphere.GetOutput().GetNumberOfPoints())


if __name__ == "__main__":
    unittest.main()


class Morph(unittest.TestCase):
    """csrbf.morph returns what `csrbf morph --json` reports, and the same points."""

    def test_same_as_the_command_line(self):
        case = os.path.join(EXAMPLES, "airfoil", "case")
        motion = os.path.join(EXAMPLES, "airfoil", "motion.json")
        with tempfile.TemporaryDirectory() as tmp:
            points, report = csrbf.morph(case, motion)
            self.assertEqual(points.shape, (7872, 3))
            self.assertFalse(report["written"])
            self.assertEqual(report["quality"]["after"]["inverted_cells"], 0)
            self.assertGreater(report["quality"]["after"]["polyhedra"]["max_non_orthogonality"], 30)
            out = os.path.join(tmp, "pitched")
            points2, report2 = csrbf.morph(case, motion, output=out, radius=3.0)
            self.assertTrue(report2["written"])
            self.assertEqual(report2["radius"], 3.0)
            r = subprocess.run([os.environ["CSRBF_CLI"], "morph", case, "-o", os.path.join(tmp, "cli"), "--motion", motion,
                                "--radius", "3", "--json"], capture_output=True, text=True)
            cli = json.loads(r.stdout)
            self.assertEqual(cli["quality"]["after"], report2["quality"]["after"])
            with open(os.path.join(out, "constant", "polyMesh", "points"), "rb") as f, \
                    open(os.path.join(tmp, "cli", "constant", "polyMesh", "points"), "rb") as g:
                self.assertEqual(f.read(), g.read())
            # Half the phase moves every point half as far.
            half, _ = csrbf.morph(case, motion, radius=3.0, phase=0.5)
            base, _ = csrbf.morph(case, motion, radius=3.0, phase=0.0)
            np.testing.assert_allclose(half - base, 0.5 * (points2 - base), atol=1e-14)

    def test_points_and_a_dict_against_a_dense_solve(self):
        # A 7 x 7 x 7 grid of points, its bottom bumped by displacements given as an array aligned
        # with the patch's indices, its top fixed: the moved points against numpy's dense solve of
        # the same system (moving controls and the fixed ones within R of one).
        g = np.stack(np.meshgrid(*[np.linspace(0, 1, 7)] * 3, indexing="ij"), -1).reshape(-1, 3)
        bottom, top = np.flatnonzero(g[:, 2] == 0), np.flatnonzero(g[:, 2] == 1)
        d = np.zeros((len(bottom), 3))
        d[:, 2] = 0.02 * np.sin(np.pi * g[bottom, 0]) * np.sin(np.pi * g[bottom, 1])
        radius = 0.45
        motion = {"radius": radius, "kernel": "c2", "patches": {"bottom": {"displacements": d}, "top": "fixed"}}
        moved, report = csrbf.morph(g, motion, patches={"bottom": bottom, "top": top[::-1]})
        self.assertEqual(moved.shape, g.shape)
        self.assertEqual(report["format"], "points")
        self.assertEqual(report["moving"], int((np.abs(d).sum(axis=1) > 0).sum()))
        moving = bottom[np.abs(d).sum(axis=1) > 0]
        near = [i for i in top if np.linalg.norm(g[moving] - g[i], axis=1).min() < radius]
        self.assertEqual(near, [])  # the top is 1 away: outside R of every moving point
        controls = np.concatenate([bottom, top[[np.linalg.norm(g[moving] - g[i], axis=1).min() < radius for i in top]]])
        self.assertEqual(report["controls"], len(controls))
        s = g[controls]
        dd = np.zeros((len(controls), 3))
        dd[:len(bottom)] = d
        a = wendland_c2(np.linalg.norm(s[:, None] - s[None], axis=2) / radius)
        alpha = np.linalg.solve(a, dd)
        want = g + wendland_c2(np.linalg.norm(g[:, None] - s[None], axis=2) / radius) @ alpha
        want[bottom] = g[bottom] + d  # prescribed points are placed exactly
        want[top] = g[top]
        np.testing.assert_allclose(moved, want, rtol=0, atol=1e-13)
        self.assertTrue(np.array_equal(moved[top], g[top]))
        # The same as rows [point, dx, dy, dz], and radius "auto".
        rows = np.column_stack([bottom, d])
        moved2, _ = csrbf.morph(g, {"radius": radius, "patches": {"bottom": {"displacements": rows.tolist()},
                                                                 "top": "fixed"}},
                                patches={"bottom": bottom, "top": top})
        self.assertTrue(np.array_equal(moved, moved2))
        _, auto = csrbf.morph(g, {"patches": {"bottom": {"displacements": d}, "top": "fixed"}},
                              patches={"bottom": bottom, "top": top}, radius="auto")
        self.assertIn("boundary's spacing", auto["radius_why"])

    def test_a_dict_motion_on_a_case_equals_its_file(self):
        case = os.path.join(EXAMPLES, "airfoil", "case")
        path = os.path.join(EXAMPLES, "airfoil", "motion.json")
        with open(path) as f:
            motion = json.load(f)
        a, ra = csrbf.morph(case, path)
        b, rb = csrbf.morph(case, motion)
        self.assertTrue(np.array_equal(a, b))
        self.assertEqual(ra["quality"], rb["quality"])
        self.assertEqual(rb["motion"] if "motion" in rb else "motion (dict)", "motion (dict)")

    def test_points_and_dicts_refuse_bad_arguments_by_name(self):
        g = np.stack(np.meshgrid(*[np.linspace(0, 1, 4)] * 3, indexing="ij"), -1).reshape(-1, 3)
        bottom = np.flatnonzero(g[:, 2] == 0)
        motion = {"radius": 0.6, "patches": {"bottom": {"translate": [0, 0, 0.01]}}}
        cases = [
            (dict(), ValueError, "patches: mesh is an array of points"),
            (dict(patches={"bottom": [0, 1, 999]}), ValueError, r"patches\['bottom'\]\[2\] is 999: mesh has 64 points"),
            (dict(patches={"bottom": [0.5]}), TypeError, r"patches\['bottom'\] must be a 1-D array of point indices"),
            (dict(patches={"bottom": bottom}, output="x.vtu"), ValueError, "has no file to write"),
            (dict(patches={"bottom": bottom}, radius="big"), TypeError, "radius must be a number > 0"),
            (dict(patches={"wall": bottom}), ValueError, "no patch 'bottom'"),
        ]
        for kwargs, error, text in cases:
            with self.subTest(kwargs=list(kwargs)), self.assertRaisesRegex(error, text):
                csrbf.morph(g, motion, **kwargs)
        with self.assertRaisesRegex(ValueError, "patches.bottom.translate"):
            csrbf.morph(g, {"radius": 0.6, "patches": {"bottom": {"translate": [0, 0]}}}, patches={"bottom": bottom})
        with self.assertRaisesRegex(ValueError, "has 2 rows, patches\\['bottom'\\] 16 points"):
            csrbf.morph(g, {"radius": 0.6, "patches": {"bottom": {"displacements": np.zeros((2, 3))}}},
                        patches={"bottom": bottom})
        with self.assertRaisesRegex(ValueError, "motion: a number in it is not finite"):
            csrbf.morph(g, {"radius": 0.6, "patches": {"bottom": {"translate": [0, 0, float("nan")]}}},
                        patches={"bottom": bottom})
        with self.assertRaisesRegex(ValueError, r"the greedy tolerance must be in \(0, 1\], got 2"):
            csrbf.morph(g, motion, patches={"bottom": bottom}, greedy=2.0)
        with self.assertRaisesRegex(TypeError, "radius must be a number > 0"):
            csrbf.morph(g, motion, patches={"bottom": bottom}, radius=True)
        with self.assertRaisesRegex(TypeError, "its keys are patch names"):
            csrbf.morph(g, motion, patches={1: bottom})
        with self.assertRaisesRegex(TypeError, "motion must be a motion file's path or a dict"):
            csrbf.morph(g, 3, patches={"bottom": bottom})
        with self.assertRaisesRegex(ValueError, "patches: only for a mesh given as an array"):
            csrbf.morph(os.path.join(EXAMPLES, "airfoil", "case"), motion, patches={"bottom": bottom})

    def test_time_folders_and_greedy_budget(self):
        # A case whose mesh already moved (time 0.5 holds the points a first morph wrote) is morphed
        # from that time's mesh with time="latest" or time=0.5, as `csrbf morph -time`.
        motion = os.path.join(EXAMPLES, "airfoil", "motion.json")
        with tempfile.TemporaryDirectory() as tmp:
            case = os.path.join(tmp, "case")
            shutil.copytree(os.path.join(EXAMPLES, "airfoil", "case"), case)
            first, _ = csrbf.morph(case, motion, output=os.path.join(tmp, "first"))
            os.makedirs(os.path.join(case, "0.5", "polyMesh"))
            shutil.copy(os.path.join(tmp, "first", "constant", "polyMesh", "points"),
                        os.path.join(case, "0.5", "polyMesh", "points"))
            still, report = csrbf.morph(case, motion, time="latest", phase=0.0)
            self.assertEqual(report["time"], "0.5")
            np.testing.assert_array_equal(still, first)
            again, report = csrbf.morph(case, motion, time=0.5)
            self.assertEqual(report["time"], "0.5")
            twice, _ = csrbf.morph(case, motion)
            self.assertGreater(np.abs(again - twice).max(), 1e-3)  # moved from the moved mesh, not constant's
            with self.assertRaisesRegex(csrbf.FileError, "0.7"):
                csrbf.morph(case, motion, time=0.7)
            with self.assertRaisesRegex(TypeError, "time must be"):
                csrbf.morph(case, motion, time=True)
        # greedy_budget: unbounded, greedy runs to its tolerance with fewer controls than the plain fit.
        case = os.path.join(EXAMPLES, "airfoil", "case")
        _, plain = csrbf.morph(case, motion)
        _, report = csrbf.morph(case, motion, greedy=1e-4, greedy_budget=1e6)
        self.assertIsNone(report["greedy_stopped"])
        self.assertLess(report["controls"], plain["controls"])
        self.assertLessEqual(report["max_boundary_error"], 1e-4 * report["max_displacement"])
        with self.assertRaisesRegex(ValueError, "give greedy= too"):
            csrbf.morph(case, motion, greedy_budget=0.5)
        # levels: two, exact at the boundary as one is, and the report says how they were made.
        moved, two = csrbf.morph(case, motion, levels=2)
        self.assertEqual(two["levels"], 2)
        self.assertEqual(plain["levels"], 1)
        self.assertLess(two["two_levels"]["coarse_controls"], two["controls"])
        self.assertEqual(two["two_levels"]["coarse_spacing"], two["radius"] / 4)
        self.assertLessEqual(two["max_boundary_error"], 1e-12 * two["max_displacement"])
        self.assertEqual(two["quality"]["after"]["inverted_cells"], 0)
        with self.assertRaisesRegex(ValueError, 'levels must be "auto", 1 or 2, got 3'):
            csrbf.morph(case, motion, levels=3)
        with self.assertRaisesRegex(ValueError, "levels must be"):
            csrbf.morph(case, motion, levels=1 << 70)
        with self.assertRaisesRegex(TypeError, "levels must be"):
            csrbf.morph(case, motion, levels=True)
        self.assertEqual(csrbf.morph(case, motion, levels=np.int64(2))[1]["levels"], 2)
        with self.assertRaisesRegex(ValueError, "two levels and greedy exclude each other"):
            csrbf.morph(case, motion, levels=2, greedy=1e-3)
        with self.assertRaisesRegex(ValueError, r"the greedy budget must be in \[0, 1e6\], got -1"):
            csrbf.morph(case, motion, greedy=1e-3, greedy_budget=-1)

    def test_errors(self):
        case = os.path.join(EXAMPLES, "airfoil", "case")
        with tempfile.TemporaryDirectory() as tmp:
            bad = os.path.join(tmp, "m.json")
            with open(bad, "w") as f:
                json.dump({"patches": {"wing": "fixed"}}, f)
            with self.assertRaisesRegex(ValueError, "the radius must be a finite number > 0, got -1"):
                csrbf.morph(case, bad, radius=-1.0)
            with self.assertRaisesRegex(csrbf.FileError, "no patch 'wing'"):
                csrbf.morph(case, bad, radius=1.0)
            steep = os.path.join(tmp, "steep.json")
            with open(steep, "w") as f:
                json.dump({"radius": 0.5, "patches": {"airfoil": {"translate": [0, 0.6, 0]}, "farfield": "fixed"}}, f)
            _, report = csrbf.morph(case, steep)
            self.assertGreater(report["quality"]["after"]["inverted_cells"], 0)
            self.assertLess(report["safe_phase"], 1.0)
            with self.assertRaisesRegex(ValueError, "inverts"):
                csrbf.morph(case, steep, output=os.path.join(tmp, "x"))
            self.assertFalse(os.path.exists(os.path.join(tmp, "x")))

    def test_options_are_checked_as_the_command_checks_them(self):
        case = os.path.join(EXAMPLES, "airfoil", "case")
        motion = os.path.join(EXAMPLES, "airfoil", "motion.json")
        for kwargs, text in (({"phase": 2.0}, "phase must be in"), ({"phase": -1.0}, "phase must be in"),
                             ({"greedy": 2.0}, "greedy tolerance"), ({"radius": 0.0}, "radius must be"),
                             ({"kernel": "c3"}, "kernel")):
            with self.assertRaisesRegex(ValueError, text):
                csrbf.morph(case, motion, **kwargs)
