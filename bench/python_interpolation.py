#!/usr/bin/python3
"""csrbf.Interpolator against what SciPy users pick, in one run: 2-D scattered data (Franke's
function on seeded uniform points in the unit square), P = 1e4, 1e5, 1e6 data points, Q = 2e5 and
1e6 evaluation points.

  csrbf single      csrbf.Interpolator(points, f)                       (C2, 40 neighbours)
  csrbf multiscale  csrbf.Interpolator(points, f, method="multiscale", degree=1)
  scipy tps-50      scipy.interpolate.RBFInterpolator(points, f, neighbors=50)  (thin-plate, SciPy's default)
  scipy tps global  RBFInterpolator(points, f)                           (P = 1e4 only: O(P^3), P^2 memory)
  griddata linear   scipy.interpolate.griddata(points, f, x, "linear")  (Delaunay; NaN outside the hull)

Each case runs in a child process of its own, so that its peak memory (ru_maxrss) is its own; csrbf's
cases are run `--repeats` times and their median reported, SciPy's once where one run takes more than
10 s. Errors are RMS and max against the exact function at the evaluation points (seeded, in the
square). Then the multiscale trade-off at P = 1e5, Q = 2e5: levels 1-6 and 20, 40, 80 neighbours.

  /usr/bin/python3 bench/python_interpolation.py [--quick] [--json out.json] [--plot docs/python_interpolation.png]

Needs the built module (PYTHONPATH=build/python, found by default) and python3-matplotlib for the plot.
"""

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
MODULE = os.path.join(HERE, "..", "build", "python")


def franke(x, y):
    import numpy as np

    return (
        0.75 * np.exp(-((9 * x - 2) ** 2 + (9 * y - 2) ** 2) / 4)
        + 0.75 * np.exp(-((9 * x + 1) ** 2) / 49 - (9 * y + 1) / 10)
        + 0.5 * np.exp(-((9 * x - 7) ** 2 + (9 * y - 3) ** 2) / 4)
        - 0.2 * np.exp(-((9 * x - 4) ** 2) - (9 * y - 7) ** 2)
    )


def run_case(method, p, q, extra):
    """In the child: fit and evaluate once; prints a JSON line."""
    import numpy as np

    rng = np.random.default_rng(20261205)
    pts = rng.random((p, 2))
    f = franke(pts[:, 0], pts[:, 1])
    x = np.random.default_rng(7).random((q, 2))
    exact = franke(x[:, 0], x[:, 1])
    t0 = time.perf_counter()
    info = {}
    if method.startswith("csrbf"):
        import csrbf

        kw = dict(extra)
        if method == "csrbf multiscale":
            kw.setdefault("method", "multiscale")
            kw.setdefault("degree", 1)
        s = csrbf.Interpolator(pts, f, **kw)
        t1 = time.perf_counter()
        y = s(x)
        st = s.stats
        info = {"levels": len(st["levels"]), "neighbors": round(st["neighbors"], 1), "solver": st["solver"]}
    elif method.startswith("scipy"):
        from scipy.interpolate import RBFInterpolator

        s = RBFInterpolator(pts, f, neighbors=None if method == "scipy tps global" else 50)
        t1 = time.perf_counter()
        y = np.concatenate([s(c) for c in np.array_split(x, max(1, q // 50000))])  # SciPy's memory: in chunks
    else:
        from scipy.interpolate import griddata

        t1 = time.perf_counter()
        y = griddata(pts, f, x, method="linear")
    t2 = time.perf_counter()
    e = y - exact
    inside = np.isfinite(e)
    out = {
        "method": method,
        "P": p,
        "Q": q,
        "fit": t1 - t0,
        "eval": t2 - t1,
        "rms": float(np.sqrt(np.mean(e[inside] ** 2))),
        "max": float(np.abs(e[inside]).max()),
        "outside": int((~inside).sum()),
        "peak_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        **info,
    }
    print(json.dumps(out))


def child(method, p, q, extra=None, timeout=3600):
    env = dict(os.environ)
    env["PYTHONPATH"] = MODULE + os.pathsep + env.get("PYTHONPATH", "")
    args = [sys.executable, __file__, "--case", method, str(p), str(q), json.dumps(extra or {})]
    r = subprocess.run(args, capture_output=True, text=True, env=env, timeout=timeout)
    if r.returncode != 0:
        return {"method": method, "P": p, "Q": q, "error": r.stderr.strip().splitlines()[-1] if r.stderr else "failed"}
    return json.loads(r.stdout.strip().splitlines()[-1])


def measured(method, p, q, repeats, extra=None):
    runs = [child(method, p, q, extra)]
    if "error" in runs[0]:
        return runs[0]
    slow = runs[0]["fit"] + runs[0]["eval"] > 10 and not method.startswith("csrbf")
    for _ in range(0 if slow else repeats - 1):
        runs.append(child(method, p, q, extra))
    best = dict(runs[0])
    for key in ("fit", "eval", "peak_mib"):
        best[key] = statistics.median(r[key] for r in runs)
    best["total"] = statistics.median(r["fit"] + r["eval"] for r in runs)
    best["runs"] = len(runs)
    return best


def table(rows):
    lines = [
        "| P | Q | method | fit s | eval s | total s | vs tps-50 | peak MiB | RMS | max | notes |",
        "|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    ref = {(r["P"], r["Q"]): r["total"] for r in rows if r.get("method") == "scipy tps-50" and "total" in r}
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['P']:.0e} | {r['Q']:.0e} | {r['method']} | | | | | | | | {r['error'][:80]} |")
            continue
        speed = ref.get((r["P"], r["Q"]))
        ratio = f"{speed / r['total']:.1f}x" if speed else ""
        notes = []
        if "levels" in r:
            notes.append(f"{r['levels']} level(s), {r['neighbors']} nb, {r['solver']}")
        if r.get("outside"):
            notes.append(f"{r['outside']} NaN outside the hull")
        if r.get("runs", 1) > 1:
            notes.append(f"median of {r['runs']}")
        lines.append(
            f"| {r['P']:.0e} | {r['Q']:.0e} | {r['method']} | {r['fit']:.2f} | {r['eval']:.2f} | {r['total']:.2f} | "
            f"{ratio} | {r['peak_mib']:.0f} | {r['rms']:.2e} | {r['max']:.2e} | {'; '.join(notes)} |"
        )
    return "\n".join(lines)


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--case":
        run_case(sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), json.loads(sys.argv[5]))
        return
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="P = 1e4 and 1e5, Q = 2e5 only; one run each")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--json", help="write every figure here")
    ap.add_argument("--plot", help="write the time-against-P plot (PNG) here")
    a = ap.parse_args()
    repeats = 1 if a.quick else a.repeats
    sizes = [10_000, 100_000] if a.quick else [10_000, 100_000, 1_000_000]
    queries = [200_000] if a.quick else [200_000, 1_000_000]
    rows = []
    for q in queries:
        for p in sizes:
            for method in ("csrbf single", "csrbf multiscale", "scipy tps-50", "griddata linear"):
                rows.append(measured(method, p, q, repeats))
                print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
            if p == 10_000 and q == 200_000:
                rows.append(measured("scipy tps global", p, q, 1))
                print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    print("## 2-D scattered data: Franke's function\n")
    print(table(rows))
    trade = []
    if not a.quick:
        for k in (20, 40, 80):
            for levels in range(1, 7):
                r = measured("csrbf single", 100_000, 200_000, 1, {"neighbors": k, "levels": levels, "degree": 1})
                r["neighbors_asked"] = k
                trade.append(r)
                print(json.dumps(r), file=sys.stderr, flush=True)
        print("\n## Multiscale trade-off, P = 1e5, Q = 2e5 (degree 1; one run each)\n")
        print("| neighbours | levels | fit + eval s | RMS | max |")
        print("|---:|---:|---:|---:|---:|")
        for r in trade:
            if "error" in r:
                print(f"| {r.get('neighbors_asked')} | | | | {r['error'][:60]} |")
                continue
            print(f"| {r['neighbors_asked']} | {r['levels']} | {r['total']:.2f} | {r['rms']:.2e} | {r['max']:.2e} |")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump({"rows": rows, "tradeoff": trade}, fh, indent=1)
    if a.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
        for method, style in (("csrbf single", "o-"), ("csrbf multiscale", "s-"), ("scipy tps-50", "^--"),
                              ("griddata linear", "v:"), ("scipy tps global", "x")):
            pts = [r for r in rows if r.get("method") == method and r["Q"] == queries[0] and "total" in r]
            if pts:
                axes[0].loglog([r["P"] for r in pts], [r["total"] for r in pts], style, label=method)
        axes[0].set_xlabel("data points P")
        axes[0].set_ylabel(f"fit + evaluation of Q = {queries[0]:.0e} points, s")
        axes[0].set_title("Franke's function, 2-D, time against P")
        axes[0].grid(True, which="both", alpha=0.3)
        axes[0].legend()
        for k in (20, 40, 80):
            pts = [r for r in trade if r.get("neighbors_asked") == k and "total" in r]
            if pts:
                axes[1].loglog([r["total"] for r in pts], [r["rms"] for r in pts], "o-", label=f"csrbf, {k} neighbours, levels 1-6")
        for r in rows:
            if r.get("P") == 100_000 and r.get("Q") == 200_000 and r.get("method", "").startswith(("scipy", "griddata")) and "total" in r:
                axes[1].loglog([r["total"]], [r["rms"]], "*", markersize=12, label=r["method"])
        axes[1].set_xlabel("fit + evaluation, s (P = 1e5, Q = 2e5)")
        axes[1].set_ylabel("RMS error")
        axes[1].set_title("accuracy against time")
        axes[1].grid(True, which="both", alpha=0.3)
        axes[1].legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(a.plot, dpi=110)


if __name__ == "__main__":
    main()
