#!/usr/bin/python3
"""csrbf's fit against SciPy's, one run, the same points and radius (issue 32, docs/PERFORMANCE.md).

SciPy the way its users build a compactly supported RBF system: cKDTree's sparse_distance_matrix
within R, the Wendland C2 values, a CSR matrix, and scipy.sparse.linalg.cg for one right-hand side
with the Jacobi preconditioner (A's diagonal is phi(0) = 1 everywhere, so it is plain CG), to a
relative residual of 1e-10. csrbf fits all three displacement components (csrbf.SpaceMap, solver
'auto', the same C2 kernel), in the same process, one after the other. Each timing is a median of
--repeat runs; the relative residual of both solutions is checked here, with A built by SciPy.

  /usr/bin/python3 bench/fit_scipy.py --module-dir build/python --n 1000000 --geometry sphere cube plane
"""
import argparse
import json
import math
import statistics
import sys
import time

import numpy as np
import scipy
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.spatial import cKDTree


def sphere_points(n):
    """The Fibonacci lattice of csrbf bench's scale and solvers scenarios."""
    i = np.arange(n, dtype=np.float64)
    y = 1.0 - 2.0 * (i + 0.5) / n
    r = np.sqrt(np.maximum(0.0, 1.0 - y * y))
    a = math.pi * (3.0 - math.sqrt(5.0)) * i
    return np.column_stack([r * np.cos(a), y, r * np.sin(a)])


def geometry(name, n, neighbours):
    """Points, destinations and R for about `neighbours` other points within R of each."""
    if name == "sphere":
        s = sphere_points(n)
        bump = np.sin(5 * s[:, 0]) * np.cos(4 * s[:, 1]) * np.sin(3 * s[:, 2] + 1)
        return s, s * (1.0 + 0.02 * bump)[:, None], math.sqrt(4.0 * neighbours / n)
    rng = np.random.default_rng(20261201)
    if name == "cube":
        s = rng.random((n, 3))
        radius = (3.0 * neighbours / (4.0 * math.pi * n)) ** (1.0 / 3.0)
    else:  # plane: the unit square at z = 0, a 2-D point set
        s = np.column_stack([rng.random((n, 2)), np.zeros(n)])
        radius = math.sqrt(neighbours / (math.pi * n))
    d = s + 0.02 * np.column_stack([np.sin(5 * s[:, 1]), np.cos(4 * s[:, 2]), np.sin(3 * s[:, 0] + 1)])
    return s, d, radius


def wendland_c2(r):
    return (1.0 - r) ** 4 * (4.0 * r + 1.0)


def scipy_matrix(s, radius):
    tree = cKDTree(s)
    coo = tree.sparse_distance_matrix(tree, radius, output_type="coo_matrix")
    # The pairs (i, i) are among them, at distance 0: the diagonal phi(0) = 1.
    return sp.csr_matrix((wendland_c2(coo.data / radius), (coo.row, coo.col)), shape=(len(s), len(s)))


def scipy_fit(s, d, radius, tol):
    """One right-hand side, as the baseline is stated: the x component of the displacement."""
    t0 = time.perf_counter()
    a = scipy_matrix(s, radius)
    b = d[:, 0] - s[:, 0]
    steps = [0]

    def count(_):
        steps[0] += 1

    jacobi = sp.diags(1.0 / a.diagonal())
    kw = {"rtol": tol} if tuple(int(v) for v in scipy.__version__.split(".")[:2]) >= (1, 12) else {"tol": tol}
    x, info = spla.cg(a, b, M=jacobi, maxiter=100000, callback=count, atol=0.0, **kw)
    seconds = time.perf_counter() - t0
    residual = np.linalg.norm(b - a @ x) / np.linalg.norm(b)
    return seconds, steps[0], residual, info, a


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--module-dir", default="build/python", help="where csrbf's Python module is")
    ap.add_argument("--n", type=int, nargs="+", default=[100000])
    ap.add_argument("--geometry", nargs="+", default=["sphere", "cube"], choices=["sphere", "cube", "plane"])
    ap.add_argument("--neighbours", type=float, default=25.0)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--solver", default="auto", help="csrbf's solver (auto, cg, pcg, ...)")
    ap.add_argument("--no-scipy", action="store_true", help="csrbf alone (a quick look)")
    ap.add_argument("--tolerance", type=float, default=1e-10)
    args = ap.parse_args()
    sys.path.insert(0, args.module_dir)
    import csrbf

    for g in args.geometry:
        for n in args.n:
            s, d, radius = geometry(g, n, args.neighbours)
            csrbf_times, scipy_times = [], []
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                m = csrbf.SpaceMap(s, d, radius, "c2", solver=args.solver, memory_limit=16.0)
                csrbf_times.append(time.perf_counter() - t0)
                stats = m.stats
                if not args.no_scipy:
                    seconds, steps, scipy_residual, info, a = scipy_fit(s, d, radius, args.tolerance)
                    scipy_times.append(seconds)
            row = {"geometry": g, "n": n, "radius": radius, "neighbours": stats["mean_neighbors"],
                   "csrbf_s": statistics.median(csrbf_times), "csrbf_solver": stats["solver"],
                   "csrbf_steps": stats["iterations"], "csrbf_residual_controls": stats["residual_relative"],
                   "repeat": args.repeat, "threads": csrbf.threads() if hasattr(csrbf, "threads") else None}
            if not args.no_scipy:
                alpha = np.asarray(m.coefficients)
                g_all = d - s
                row["csrbf_residual"] = float(max(np.linalg.norm(g_all[:, c] - a @ alpha[:, c]) /
                                                  np.linalg.norm(g_all[:, c]) for c in range(3)))
                row.update({"scipy_s": statistics.median(scipy_times), "scipy_steps": steps,
                            "scipy_residual": float(scipy_residual), "scipy_converged": info == 0,
                            "ratio": statistics.median(csrbf_times) / statistics.median(scipy_times),
                            "scipy": scipy.__version__})
            print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
