"""csrbf.Interpolator against a dense solve of the same system in numpy (the independent slow
solution), for D = 1, 2, 3, values of 1, 2, 6 and (3, 3) components, each degree, with and without
smoothing, in float64 and float32; the multiscale levels against dense solves level by level; the
gradient against the closed form; pickling, a multiprocessing pool, threads, the GIL, and the errors.
Run by CTest as `python` (unittest discovers this file beside test_csrbf.py)."""

import ast
import multiprocessing
import os
import pickle
import re
import subprocess
import sys
import threading
import time
import unittest

import numpy as np

import csrbf


def wendland(kernel, r):
    r = np.minimum(r, 1.0)
    s = 1.0 - r
    if kernel == "c0":
        return s**2
    if kernel == "c2":
        return s**4 * (4 * r + 1)
    if kernel == "c4":
        return s**6 * (35 * r**2 + 18 * r + 3)
    return s**8 * (32 * r**3 + 25 * r**2 + 8 * r + 1)


def wendland_derivative_over_r(kernel, r):
    """phi'(r) / r (finite at 0 for C2-C6)."""
    r = np.minimum(r, 1.0)
    s = 1.0 - r
    if kernel == "c2":
        return -20 * s**3
    if kernel == "c4":
        return -56 * s**5 * (5 * r + 1)
    return -22 * s**7 * ((16 * r + 7) * r + 1)


def poly_basis(x, degree):
    if degree < 0:
        return np.zeros((len(x), 0))
    if degree == 0:
        return np.ones((len(x), 1))
    return np.hstack([np.ones((len(x), 1)), x])


def dense_fit(points, values, radius, kernel="c2", degree=-1, smoothing=0.0):
    """[[A + Lambda, P], [P^T, 0]] [alpha; beta] = [f; 0], dense. Returns (alpha, beta)."""
    p = len(points)
    f = values.reshape(p, -1)
    d = np.linalg.norm(points[:, None, :] - points[None, :, :], axis=2)
    a = wendland(kernel, d / radius) + np.diag(np.broadcast_to(np.asarray(smoothing, float), (p,)))
    pm = poly_basis(points, degree)
    t = pm.shape[1]
    m = np.block([[a, pm], [pm.T, np.zeros((t, t))]])
    sol = np.linalg.solve(m, np.vstack([f, np.zeros((t, f.shape[1]))]))
    return sol[:p], sol[p:]


def dense_eval(points, alpha, beta, radius, x, kernel="c2", degree=-1):
    d = np.linalg.norm(x[:, None, :] - points[None, :, :], axis=2)
    return wendland(kernel, d / radius) @ alpha + poly_basis(x, degree) @ beta


def dense_gradient(points, alpha, beta, radius, x, kernel="c2", degree=-1):
    diff = x[:, None, :] - points[None, :, :]  # (q, p, D)
    r = np.linalg.norm(diff, axis=2) / radius
    w = wendland_derivative_over_r(kernel, r) * (r < 1) / radius**2  # (q, p)
    g = np.einsum("qp,pv,qpd->qvd", w, alpha, diff)
    if degree == 1:
        g += beta[1:].T[None, :, :]
    return g


def franke(x, y):
    return (
        0.75 * np.exp(-((9 * x - 2) ** 2 + (9 * y - 2) ** 2) / 4)
        + 0.75 * np.exp(-((9 * x + 1) ** 2) / 49 - (9 * y + 1) / 10)
        + 0.5 * np.exp(-((9 * x - 7) ** 2 + (9 * y - 3) ** 2) / 4)
        - 0.2 * np.exp(-((9 * x - 4) ** 2) - (9 * y - 7) ** 2)
    )


class Named(csrbf.Interpolator):
    """A subclass with an argument and an attribute of its own (pickled by name, so at module level)."""

    def __init__(self, points, values, name="f", **kwargs):
        super().__init__(points, values, **kwargs)
        self.name = name


def evaluate_in_child(args):
    s, x = args
    return s(x)


class InterpolatorAgainstDenseSolve(unittest.TestCase):
    def check(self, dim, shape, degree, smoothing, kernel="c2", p=240):
        rng = np.random.default_rng(1000 * dim + 10 * len(shape) + degree + 3)
        pts = rng.random((p, dim))
        if dim == 1:  # random points on a line come too close (1e-5 apart) for a well-conditioned test
            pts = ((np.arange(p) + 0.8 * rng.random(p)) / p)[:, None]
        values = rng.standard_normal((p,) + shape)
        radius = {1: 0.08, 2: 0.25, 3: 0.4}[dim]
        s = csrbf.Interpolator(pts, values, radius=radius, kernel=kernel, degree=degree, smoothing=smoothing)
        alpha, beta = dense_fit(pts, values, radius, kernel, degree, smoothing)
        x = rng.random((300, dim)) * 1.2 - 0.1  # some beyond the points' box
        want = dense_eval(pts, alpha, beta, radius, x, kernel, degree).reshape((300,) + shape)
        got = s(x)
        self.assertEqual(got.shape, (300,) + shape)
        self.assertEqual(got.dtype, np.float64)
        scale = np.abs(want).max()
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-9 * scale, err_msg=f"D={dim} {shape} degree {degree}")
        # At the points: the data (interpolation), or the smoothed system's f - lambda alpha.
        at = s(pts).reshape(p, -1)
        expect = values.reshape(p, -1) - np.asarray(smoothing).reshape(-1, 1) * alpha if np.any(smoothing) else values.reshape(p, -1)
        np.testing.assert_allclose(at, expect, rtol=0, atol=1e-9 * np.abs(values).max())
        if kernel != "c0":
            g = s.gradient(x[:20])
            self.assertEqual(g.shape, (20,) + shape + (dim,))
            gw = dense_gradient(pts, alpha, beta, radius, x[:20], kernel, degree).reshape((20,) + shape + (dim,))
            np.testing.assert_allclose(g, gw, rtol=0, atol=1e-8 * np.abs(gw).max())
        # float32 values and points: float32 results, within float's precision of the dense solve.
        s32 = csrbf.Interpolator(pts.astype(np.float32), values.astype(np.float32), radius=radius, kernel=kernel,
                                 degree=degree, smoothing=smoothing)
        got32 = s32(x.astype(np.float32))
        self.assertEqual(got32.dtype, np.float32)
        np.testing.assert_allclose(got32, want, rtol=0, atol=2e-4 * scale)

    def test_every_dimension_value_shape_degree_and_smoothing(self):
        for dim in (1, 2, 3):
            for shape in ((), (2,), (6,), (3, 3)):
                for degree in (-1, 0, 1):
                    self.check(dim, shape, degree, 0.0)
                self.check(dim, shape, 1, 0.01)
        rng = np.random.default_rng(5)
        self.check(2, (), 0, rng.random(240) * 0.05)  # one smoothing a point

    def test_every_kernel(self):
        for kernel in ("c0", "c2", "c4", "c6"):
            self.check(2, (2,), 0, 0.0, kernel=kernel)

    def test_duplicates_are_allowed_with_smoothing_and_refused_without(self):
        rng = np.random.default_rng(7)
        pts = rng.random((100, 2))
        pts[50] = pts[10]
        f = rng.random(100)
        with self.assertRaisesRegex(ValueError, r"points 10 and 50 are at the same position"):
            csrbf.Interpolator(pts, f, radius=0.3)
        s = csrbf.Interpolator(pts, f, radius=0.3, smoothing=0.1)
        alpha, beta = dense_fit(pts, f, 0.3, smoothing=0.1)
        np.testing.assert_allclose(s(pts[:5]), dense_eval(pts, alpha, beta, 0.3, pts[:5])[:, 0], atol=1e-10)

    def test_no_silent_overflow_far_beyond_the_points(self):
        p = np.random.default_rng(1).random((50, 2)) * 1e-100
        s = csrbf.Interpolator(p, np.ones(50), degree=0)
        with self.assertRaisesRegex(ValueError, r"x\[0\] = \(1e\+210, 0\): the interpolant overflows there"):
            s([1e210, 0.0])

    def test_strictly_local_without_a_polynomial(self):
        pts = np.random.default_rng(2).random((200, 3))
        s = csrbf.Interpolator(pts, np.ones(200), radius=0.2)
        far = np.array([[5.0, 5.0, 5.0], [-3.0, 0.5, 0.5]])
        self.assertEqual(s(far).tolist(), [0.0, 0.0])


class Multiscale(unittest.TestCase):
    def test_levels_equal_dense_solves_level_by_level(self):
        rng = np.random.default_rng(11)
        pts = rng.random((1500, 2))
        f = np.stack([franke(pts[:, 0], pts[:, 1]), pts[:, 0] ** 2], axis=1)
        s = csrbf.Interpolator(pts, f, levels=3, neighbors=25, degree=1)
        self.assertEqual(s.levels, 3)
        state = s.__getstate__()
        self.assertEqual((state["format"], state["version"]), ("csrbf.Interpolator", 2))
        levels = state["levels"]
        self.assertEqual(len(levels[-1]["points"]), 1500)  # the finest level holds every point
        sizes = [len(level["points"]) for level in levels]
        self.assertTrue(sizes[0] < sizes[1] < sizes[2], sizes)
        # Nested: every coarse point is a finer level's point.
        for coarse, fine in zip(levels, levels[1:]):
            fine_set = {tuple(p) for p in fine["points"]}
            self.assertTrue(all(tuple(p) in fine_set for p in coarse["points"]))
        x = rng.random((400, 2))
        residual = f.copy()
        want = np.zeros((400, 2))
        for k, level in enumerate(levels):
            radius, lp = level["radius"], level["points"]
            idx = np.array([np.flatnonzero((pts == q).all(axis=1))[0] for q in lp])
            degree = 1 if k == 0 else -1
            alpha, beta = dense_fit(lp, residual[idx], radius, degree=degree)
            want += dense_eval(lp, alpha, beta, radius, x, degree=degree)
            residual -= dense_eval(lp, alpha, beta, radius, pts, degree=degree)
        np.testing.assert_allclose(s(x), want, rtol=0, atol=1e-9 * np.abs(want).max())
        np.testing.assert_allclose(s(pts), f, rtol=0, atol=1e-9)  # still interpolates
        self.assertEqual(len(s.stats["levels"]), 3)

    def test_multiscale_is_far_more_accurate_than_one_scale_on_franke(self):
        rng = np.random.default_rng(3)
        pts = rng.random((10000, 2))
        f = franke(pts[:, 0], pts[:, 1])
        x = rng.random((20000, 2)) * 0.9 + 0.05
        exact = franke(x[:, 0], x[:, 1])
        one = csrbf.Interpolator(pts, f)
        many = csrbf.Interpolator(pts, f, method="multiscale")
        rms_one = np.sqrt(np.mean((one(x) - exact) ** 2))
        rms_many = np.sqrt(np.mean((many(x) - exact) ** 2))
        self.assertGreater(many.levels, 2)
        self.assertLess(rms_many * 20, rms_one, (rms_one, rms_many, many.stats))

    def test_automatic_radius_reaches_its_neighbours(self):
        pts = np.random.default_rng(4).random((5000, 2))
        for k in (10, 40):
            s = csrbf.Interpolator(pts, pts[:, 0], neighbors=k)
            self.assertTrue(s.stats["radius_auto"])
            self.assertAlmostEqual(s.stats["neighbors"], k, delta=0.15 * k)

    def test_automatic_radius_on_a_cluster_keeps_the_memory_limit(self):
        # 1e5 points in a box of side 1e-3 and 10 far away: the guess from the box's volume holds the
        # whole cluster, whose every distance took 4.1 GB (and 30-50 s) under a limit of 0.5 GB.
        # In a child of its own, for its peak memory.
        code = (
            "import resource, numpy as np, csrbf\n"
            "rng = np.random.default_rng(1)\n"
            "pts = np.vstack([1e-3 * rng.random((100000, 2)), 5 + rng.random((10, 2))])\n"
            "s = csrbf.Interpolator(pts, np.sin(1e3 * pts[:, 0]), memory_limit=0.5)\n"
            "print(s.stats['neighbors'], resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)\n"
        )
        r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
        self.assertEqual(r.returncode, 0, r.stderr)
        neighbours, peak_mib = map(float, r.stdout.split())
        self.assertAlmostEqual(neighbours, 40, delta=2)
        self.assertLess(peak_mib, 512)


class PythonHabits(unittest.TestCase):
    def setUp(self):
        rng = np.random.default_rng(8)
        self.pts = rng.random((3000, 3))
        self.vals = rng.standard_normal((3000, 6))
        self.s = csrbf.Interpolator(self.pts, self.vals, radius=0.15, degree=0)
        self.x = rng.random((1000, 3))

    def test_one_point_and_out(self):
        one = self.s(self.x[0])
        self.assertEqual(one.shape, (6,))
        np.testing.assert_array_equal(one, self.s(self.x[:1])[0])
        out = np.empty((1000, 6))
        r = self.s(self.x, out=out)
        self.assertIs(r, out)
        np.testing.assert_array_equal(out, self.s(self.x))
        with self.assertRaisesRegex(ValueError, r"out must be .*\(1000, 6\) float64.*its shape is \(1000, 3\)"):
            self.s(self.x, out=np.empty((1000, 3)))
        with self.assertRaisesRegex(ValueError, r"its dtype is float32"):
            self.s(self.x, out=np.empty((1000, 6), np.float32))
        s1 = csrbf.Interpolator(self.pts[:, :1][:200] * 0 + np.arange(200)[:, None], np.arange(200.0), radius=3.0)
        self.assertAlmostEqual(float(s1(7.0)), 7.0, places=9)  # a scalar point of 1-D data

    def test_pickle_keeps_the_fit(self):
        data = pickle.dumps(self.s)
        t = pickle.loads(data)
        np.testing.assert_allclose(t(self.x), self.s(self.x), rtol=0, atol=1e-13)
        self.assertEqual(repr(t), repr(self.s))
        self.assertEqual(t.stats["levels"], self.s.stats["levels"])
        m = csrbf.Interpolator(self.pts, self.vals[:, 0], levels=3, degree=1)
        np.testing.assert_allclose(pickle.loads(pickle.dumps(m))(self.x), m(self.x), rtol=0, atol=1e-13)
        c4 = csrbf.Interpolator(self.pts, self.vals[:, :2], radius=0.2, kernel="c4")  # the kernel is kept
        want4 = c4(self.x)
        np.testing.assert_allclose(pickle.loads(pickle.dumps(c4))(self.x), want4, rtol=0,
                                   atol=1e-12 * np.abs(want4).max())
        for broken in (b"\x80\x02ccsrbf\nInterpolator\n)\x81.", ):  # an object without a fit: an error, not a crash
            with self.assertRaisesRegex(ValueError, r"never fitted"):
                pickle.loads(broken).stats
        # The state is a versioned dict, checked: a bad part is a ValueError naming the state.
        for key, value, pattern in (("threads", 10**6, r"Interpolator state: threads"),
                                    ("levels", "levels", r"Interpolator state: levels is a str"),
                                    ("version", 3, r"not a state of this version"),
                                    ("dimension", "3", r"Interpolator state: dimension is a str"),
                                    ("value_shape", (2**31, 2**31), r"Interpolator state: value shape"),
                                    ("radius_auto", "x", r"Interpolator state: radius_auto is a str"),
                                    ("solver", 5, r"Interpolator state: solver 5"),
                                    ("neighbors", float("nan"), r"Interpolator state: neighbors nan"),
                                    ("kernel", "c3", r"Interpolator state: malformed \(kernel must be one of")):
            state = self.s.__getstate__()
            state[key] = value
            with self.assertRaisesRegex(ValueError, pattern, msg=key):
                csrbf.Interpolator.__new__(csrbf.Interpolator).__setstate__(state)
        state = self.s.__getstate__()
        state["levels"][0]["alpha"] = state["levels"][0]["alpha"][:-1]
        with self.assertRaisesRegex(ValueError, r"Interpolator state: malformed"):
            csrbf.Interpolator.__new__(csrbf.Interpolator).__setstate__(state)
        for key, value in (("solver", "bogus"), ("radius", "x"), ("center", None), ("iterations", 1.5)):
            state = self.s.__getstate__()
            state["levels"][0][key] = value
            with self.assertRaisesRegex(ValueError, r"Interpolator state: (levels\[0\]|malformed)", msg=key):
                csrbf.Interpolator.__new__(csrbf.Interpolator).__setstate__(state)
        # A state that fails leaves the object as it was.
        before = self.s(self.x)
        state = m.__getstate__()
        state["neighbors"] = "x"
        with self.assertRaises(ValueError):
            self.s.__setstate__(state)
        np.testing.assert_array_equal(self.s(self.x), before)
        # A pickle of csrbf 0.1 (its state a 12-tuple of version 1) still loads, with the same values.
        v2 = m.__getstate__()
        keys = ("neighbors", "solver", "iterations", "residual", "rms_before", "seconds")
        v1 = (1, v2["dimension"], list(v2["value_shape"]), v2["dtype"] == "float32", v2["kernel"], v2["degree"],
              [(l["radius"], l["points"], l["alpha"], l["beta"], l["center"], l["scale"], tuple(l[k] for k in keys))
               for l in v2["levels"]], v2["threads"], v2["radius_auto"], v2["neighbors"], v2["solver"],
              v2["seconds_fit"])
        old = csrbf.Interpolator.__new__(csrbf.Interpolator)
        old.__setstate__(v1)
        np.testing.assert_array_equal(old(self.x), m(self.x))
        self.assertEqual(repr(old), repr(m))
        g = pickle.loads(pickle.dumps(m)).gradient(self.x[:10])
        np.testing.assert_allclose(g, m.gradient(self.x[:10]), atol=1e-12)

    def test_subclasses_pickle_as_themselves(self):
        n = Named(self.pts, self.vals[:, 0], "temperature", radius=0.2)
        for copied in (pickle.loads(pickle.dumps(n)), __import__("copy").deepcopy(n)):
            self.assertIs(type(copied), Named)
            self.assertEqual(copied.name, "temperature")
            np.testing.assert_array_equal(copied(self.x), n(self.x))

    def test_float32_values_beyond_float32_are_an_error(self):
        p = np.linspace(0, 1, 50)[:, None]
        s = csrbf.Interpolator(p, (p[:, 0] * 3e38).astype(np.float32), radius=0.2, degree=1)
        for x in (np.array([[2.0]]), np.array([[2.0]], np.float32)):
            with self.assertRaisesRegex(ValueError, r"overflows|beyond float32"):
                s(x)
        steep = csrbf.Interpolator(p * 0.1, (p[:, 0] * 3e38).astype(np.float32), radius=0.02, degree=1)
        with self.assertRaisesRegex(ValueError, r"derivative at x\[0\] is .*beyond float32"):
            steep.gradient(np.array([[0.05]]))
        self.assertTrue(np.isfinite(s(np.array([[0.5]]))).all())

    def test_pool_of_processes(self):
        want = self.s(self.x)
        chunks = np.array_split(self.x, 4)
        for method in ("fork", "spawn"):
            with multiprocessing.get_context(method).Pool(2) as pool:
                got = pool.map(evaluate_in_child, [(self.s, c) for c in chunks])
            np.testing.assert_allclose(np.vstack(got), want, rtol=0, atol=1e-13, err_msg=method)

    def test_repr_and_properties(self):
        r = repr(self.s)
        self.assertIn("points=3000", r)
        self.assertIn("dimension=3", r)
        self.assertIn("values=(6,)", r)
        self.assertIn("degree=0", r)
        self.assertEqual(self.s.dimension, 3)
        self.assertEqual(self.s.value_shape, (6,))
        self.assertEqual(len(self.s), 3000)
        self.assertEqual(self.s.radius, 0.15)
        st = self.s.stats
        self.assertFalse(st["radius_auto"])
        self.assertLessEqual(st["residual"], 1e-6)
        for key in ("radius", "neighbors", "solver", "iterations", "residual", "levels", "seconds_fit"):
            self.assertIn(key, st)

    def test_points_on_a_curve_fit_within_a_memory_limit_that_cg_would_pass(self):
        # 1e5 2-D points on a curve: CG with Schwarz patches would hold about 0.19 GiB; the envelope
        # (small on a curve) fits in 0.1. Auto weighs it as before instead of refusing the fit.
        t = np.random.default_rng(25).random(100000)
        x = np.stack([t * 10, np.sin(t * 30)], 1)
        f = np.sin(20 * t)
        s = csrbf.Interpolator(x, f, memory_limit=0.1)
        self.assertEqual(s.stats["solver"], "envelope")
        self.assertLess(np.abs(s(x[::50]) - f[::50]).max(), 1e-9)

    def test_points_on_a_line_that_the_envelope_refuses(self):
        # 5e4 random points in 1-D at the defaults: close pairs make A nearly singular, and the envelope
        # solver Auto picks refuses a pivot of 1e-14. The general direct solver takes over and fits
        # the values to 1e-9, as CG and a solver asked for by name do.
        x = np.random.default_rng(0).random((50000, 1))
        f = np.sin(6 * x[:, 0])
        with self.assertRaisesRegex(ValueError, r"not positive definite"):
            csrbf.Interpolator(x, f, solver="envelope")
        s = csrbf.Interpolator(x, f)
        self.assertIn(s.stats["solver"], ("cholmod", "eigen"))
        self.assertLess(np.abs(s(x) - f).max(), 1e-9)
        cg = csrbf.Interpolator(x, f, solver="cg")
        probe = np.random.default_rng(1).random((1000, 1))
        # Between the closest pairs the system's condition (about 1e14) leaves the two solutions 1e-5 apart.
        self.assertLess(np.abs(s(probe) - cg(probe)).max(), 1e-4)

    def test_memory_refusal_names_what_the_schwarz_patches_need(self):
        # 3e4 scattered points: CG with the Schwarz patches reads A in place, a copy of A's rows is the
        # other path's. Under a limit between the two, the refusal says what the patches would need,
        # and that limit fits.
        x = np.random.default_rng(6).random((30000, 2))
        f = np.sin(5 * x[:, 0])
        with self.assertRaisesRegex(MemoryError, r"their copy in CG's order.*with the Schwarz patches, which read A in place, ([0-9.]+) GiB") as cm:
            csrbf.Interpolator(x, f, memory_limit=0.044)
        need = float(re.search(r"read A in place, ([0-9.]+) GiB", str(cm.exception)).group(1))
        copied = float(re.search(r"would hold ([0-9.]+) GiB", str(cm.exception)).group(1))
        self.assertLess(need, 0.8 * copied)
        s = csrbf.Interpolator(x, f, memory_limit=need + 1e-3)
        self.assertEqual(s.stats["solver"], "cg")
        self.assertLess(s.stats["levels"][0]["iterations"], 60)

    def test_threads_give_the_same_result(self):
        one = csrbf.Interpolator(self.pts, self.vals, radius=0.15, degree=0, threads=1)
        np.testing.assert_allclose(one(self.x), self.s(self.x), rtol=0, atol=1e-10)

    def test_gil_is_released_while_evaluating(self):
        rng = np.random.default_rng(9)
        big = rng.random((2_000_000, 3))
        gaps = []
        done = threading.Event()
        t0 = time.perf_counter()
        one = csrbf.Interpolator(self.pts, self.vals, radius=0.15, degree=0, threads=1)  # a core left for this thread
        worker = threading.Thread(target=lambda: (one(big), done.set()))
        last = time.perf_counter()
        worker.start()
        while not done.is_set():
            now = time.perf_counter()
            gaps.append(now - last)
            last = now
            time.sleep(0.001)
        worker.join()
        took = time.perf_counter() - t0
        # Holding the GIL for the whole call would leave one gap as long as the call.
        self.assertGreater(len(gaps), 5)
        self.assertLess(max(gaps), 0.6 * took + 0.05, (max(gaps), took))

    def test_errors_name_the_argument_shape_and_element(self):
        pts = self.pts[:100]
        cases = [
            (dict(points=pts[:, :2].reshape(-1), values=np.ones(200)), ValueError, r"points must have shape \(P, D\).*\(200,\)"),
            (dict(points=np.ones((10, 4)), values=np.ones(10)), ValueError, r"D = 1, 2 or 3.*\(10, 4\).*positive definite"),
            (dict(points=pts, values=np.ones(99)), ValueError, r"values must have shape \(P, \.\.\.\) with P = 100.*\(99,\)"),
            (dict(points=np.where(np.arange(300).reshape(100, 3) == 40, np.nan, pts), values=np.ones(100)), ValueError, r"points\[13, 1\] is nan"),
            (dict(points=pts, values=np.where(np.arange(100) == 7, np.inf, 1.0)), ValueError, r"values\[7\] is inf"),
            (dict(points=pts, values=np.ones(100), radius=-1), ValueError, r"radius must be a positive"),
            (dict(points=pts, values=np.ones(100), radius="big"), ValueError, r"radius must be a positive number or 'auto', got 'big'"),
            (dict(points=pts, values=np.ones(100), kernel="gauss"), ValueError, r"kernel must be one of"),
            (dict(points=pts, values=np.ones(100), degree=2), ValueError, r"degree must be -1"),
            (dict(points=pts, values=np.ones(100), smoothing=np.ones(5)), ValueError, r"smoothing must be a number or an array of shape \(100,\), got \(5,\)"),
            (dict(points=pts, values=np.ones(100), smoothing=-1.0), ValueError, r"smoothing is -1"),
            (dict(points=pts, values=np.ones(100), levels=0), ValueError, r"levels must be within 1\.\.12 or 'auto', got 0"),
            (dict(points=pts, values=np.ones(100), levels=2.5), TypeError, r"levels must be an integer 1\.\.12 or 'auto', got a float \(2\.5\)"),
            (dict(points=pts, values=np.ones(100), threads=1.0), TypeError, r"threads must be a positive integer, got a float"),
            (dict(points=pts, values=np.ones(100), epsilon=1.0), TypeError, r"unexpected keyword argument 'epsilon' \(SciPy's shape parameter"),
            (dict(points=pts, values=np.ones(100), method="single", levels=3), ValueError, r"method='single' with levels=3"),
            (dict(points=pts, values=np.ones(100), method="multiscale", levels=1), ValueError, r"method='multiscale' with levels=1"),
            (dict(points=pts.T, values=np.ones(3)), ValueError, r"is it transposed\? \(points.T has shape \(100, 3\)\)"),
            (dict(points=pts, values=np.ones(100), memory_limit=4e9), ValueError, r"memory_limit is in GiB.*bytes\?"),
            (dict(points=pts, values=np.ones(100), kernel="thin_plate_spline"), ValueError, r"SciPy's global kernels"),
            (dict(points=pts, values=np.ones(100), method="fast"), ValueError, r"method must be 'single' or 'multiscale'"),
            (dict(points=[[0, 0], [1]], values=[1, 2]), TypeError, r"points must be an array of numbers"),
            (dict(points=pts, values=np.ones(100, complex)), TypeError, r"values must hold real numbers.*complex128"),
            (dict(points=np.zeros((0, 2)), values=np.zeros(0)), ValueError, r"points is empty"),
            (dict(points=pts, values=np.ones((100, 0))), ValueError, r"values has no value a point"),
            (dict(points=pts, values=np.ones(100), memory_limit=0), ValueError, r"memory_limit is in GiB.*got 0"),
            (dict(points=pts, values=np.ones(100), threads=0), ValueError, r"threads must be a positive"),
            (dict(points=pts, values=np.ones(100), smoothing=True), TypeError, r"smoothing must be a number"),
            (dict(points=pts, values=np.ones(100), radius=10**400), ValueError, r"radius must be .*beyond a float"),
            (dict(points=np.ones((50, 0)), values=np.ones(50)), ValueError, r"no coordinates"),
            (dict(points=pts, values=np.ones(100), radius=0.5, neighbors=10), ValueError,
             r"neighbors=10 chooses the automatic radius, but radius=0\.5 is given"),
        ]
        for kwargs, error, pattern in cases:
            with self.assertRaisesRegex(error, pattern, msg=str(pattern)):
                csrbf.Interpolator(kwargs.pop("points"), kwargs.pop("values"), **kwargs)
        with self.assertRaisesRegex(TypeError, r"radius and the rest are keyword-only"):
            csrbf.Interpolator(pts, np.ones(100), 0.3)
        # numpy integers, None for the defaults and names in any case are taken.
        s = csrbf.Interpolator(pts, np.ones(100), levels=np.int64(2), degree=None, kernel="C2", radius="AUTO",
                               threads=np.int32(1))
        self.assertEqual(s.levels, 2)
        with self.assertRaisesRegex(ValueError, r"degree 1 needs points that span their 2-D space.*collinear"):
            t = np.linspace(0, 1, 50)
            csrbf.Interpolator(np.stack([t, 2 * t], axis=1), t, radius=0.1, degree=1)
        with self.assertRaisesRegex(MemoryError, r"limit.*csrbf.Interpolator: memory_limit is"):
            csrbf.Interpolator(self.pts, self.vals, radius=5.0, memory_limit=0.001)
        with self.assertRaisesRegex(ValueError, r"x must have shape \(Q, 3\) or \(3,\).*got \(5, 2\)"):
            self.s(np.ones((5, 2)))
        with self.assertRaisesRegex(ValueError, r"x\[1, 2\] is nan"):
            self.s(np.array([[0.5, 0.5, 0.5], [0.1, 0.2, np.nan]]))

    def test_docstrings_and_stubs(self):
        for f in (csrbf.Interpolator, csrbf.Interpolator.__call__, csrbf.Interpolator.gradient):
            self.assertIn("Examples", f.__doc__)
            self.assertIn("Parameters", f.__doc__)
        import doctest

        for f in (csrbf.Interpolator, csrbf.Interpolator.__call__, csrbf.Interpolator.gradient,
                  csrbf.Interpolator.stats):
            finder = doctest.DocTestFinder()
            runner = doctest.DocTestRunner()
            for test in finder.find(f.__doc__, "csrbf.Interpolator", globs={}):
                runner.run(test)
            self.assertEqual(runner.failures, 0, f.__doc__)
        # The parameters as Python shows them (help, inspect), __new__'s (*args, **kwargs) hidden.
        import inspect

        params = inspect.signature(csrbf.Interpolator).parameters.values()
        self.assertEqual([p.name for p in params if p.kind == p.KEYWORD_ONLY],
                         ["radius", "kernel", "degree", "smoothing", "neighbors", "levels", "method", "memory_limit",
                          "threads", "solver"])


if __name__ == "__main__":
    unittest.main()
