#!/usr/bin/python3
"""csrbf export, side by side (docs/export.md "Sizes and speeds"): for the fish, the face, the ball
(a baked contact) and a sphere of 163 842 vertices, the bytes of the morph-target file, quantized,
compressed and both, and of the CSRBF_deformation file; the bytes that carry the deformation (the
targets' accessors against the extension's); and the page's frames per second for both paths in
headless Chromium (SwiftShader): FRAMES frames drawn, each read back before the next, timed from
outside against a run that draws none (medians of three).

    /usr/bin/python3 bench/export_sizes.py [--csrbf build/bin/csrbf] [--frames 60] [--json out.json]
"""
import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EXAMPLES = os.path.join(ROOT, "examples")


def icosphere(levels):
    """An icosahedron subdivided levels times onto the unit sphere: 10 * 4^levels + 2 vertices."""
    t = (1 + 5 ** 0.5) / 2
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
         (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    v = [np.array(p, float) / np.linalg.norm(p) for p in v]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6),
         (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
         (8, 6, 7), (9, 8, 1)]
    for _ in range(levels):
        mid = {}

        def middle(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                p = v[a] + v[b]
                v.append(p / np.linalg.norm(p))
                mid[key] = len(v) - 1
            return mid[key]
        f = [g for a, b, c in f for g in ((a, middle(a, b), middle(a, c)), (b, middle(b, c), middle(a, b)),
                                         (c, middle(a, c), middle(b, c)), (middle(a, b), middle(b, c), middle(a, c)))]
    return np.array(v), np.array(f)


def sphere_scene(folder):
    """A 163 842-vertex sphere with two deformations of 12 controls each: bumps and a twist."""
    v, f = icosphere(7)
    with open(os.path.join(folder, "sphere.obj"), "w") as out:
        out.write("".join(f"v {x:.7f} {y:.7f} {z:.7f}\n" for x, y, z in v))
        out.write("".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in f))
    rng = np.random.default_rng(7)
    for name, push in (("bumps", 0.25), ("dents", -0.2)):
        s = rng.normal(size=(12, 3))
        s /= np.linalg.norm(s, axis=1, keepdims=True)
        with open(os.path.join(folder, name + ".controls"), "w") as out:
            for p in s:
                out.write(" ".join(f"{x:.6f}" for x in p) + "  " + " ".join(f"{x:.6f}" for x in p * (1 + push)) + "\n")
    phase = lambda a: {"easing": "smooth", "keys": [{"time": 0, "phase": 0}, {"time": a, "phase": 1}, {"time": 4, "phase": 0}]}
    scene = {"format": "csrbf-scene", "version": 1, "duration": 4.0, "fps": 25, "background": [0.1, 0.1, 0.15],
             "camera": {"position": [0, 0, 4.5], "focal_point": [0, 0, 0], "view_angle": 40},
             "objects": [{"name": "sphere", "mesh": "sphere.obj", "color": [0.6, 0.7, 0.9], "parts": [
                 {"name": "skin", "combine": "sum", "deformations": [
                     {"name": "bumps", "controls": "bumps.controls", "radius": 0.6, "phase": phase(1.5)},
                     {"name": "dents", "controls": "dents.controls", "radius": 0.6, "phase": phase(2.5)}]}]}]}
    path = os.path.join(folder, "sphere.scene.json")
    with open(path, "w") as out:
        json.dump(scene, out)
    return path, len(v)


def export(csrbf, scene, out, *flags, html=None):
    args = [csrbf, "export", scene, "-o", out, "--json"] + list(flags)
    if html:
        args += ["--html", html]
    p = subprocess.run(args, capture_output=True, text=True, timeout=1800)
    if p.returncode:
        sys.exit(f"{' '.join(args)}: {p.stderr}")
    return json.loads(p.stdout)


def page_fps(page, frames, path):
    """Frames a second by one path: the page draws FRAMES frames (&draw=, each read back before the
    next) before it is ready; the wall time of that run less a run that draws none, three of each,
    medians. (Inside headless Chromium, virtual time stops the page's own clock.)"""
    def run(n):
        for _ in range(3):  # a run that Chromium cut short is run again
            start = time.perf_counter()
            p = subprocess.run(["chromium", "--headless", "--no-sandbox", "--disable-gpu", "--use-gl=swiftshader",
                                "--enable-unsafe-swiftshader", "--window-size=640,480", "--virtual-time-budget=60000",
                                "--dump-dom", f"file://{page}?t=1&ui=0&path={path}&draw={n}"], capture_output=True,
                               text=True, timeout=900)
            elapsed = time.perf_counter() - start
            if "<title>ready</title>" in p.stdout:
                return elapsed
        sys.exit(f"{page}: the page did not finish drawing: {p.stderr[-1000:]}")
    base = statistics.median(run(0) for _ in range(3))
    # As many frames as take about 20 s (at most FRAMES, at least 10): a large mesh draws slowly.
    probe = max(run(10) - base, 1e-3) / 10
    frames = max(10, min(frames, int(20 / probe)))
    drawn = statistics.median(run(frames) for _ in range(3))
    return frames / max(drawn - base, 1e-9)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--csrbf", default=os.path.join(ROOT, "build", "bin", "csrbf"))
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument("--json")
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="csrbf-export-sizes-")
    try:
        big, nv = sphere_scene(tmp)
        scenes = [("fish", os.path.join(EXAMPLES, "fish.scene.json")), ("face", os.path.join(EXAMPLES, "face.scene.json")),
                  ("ball (contact, baked)", os.path.join(EXAMPLES, "ball.scene.json")), (f"sphere ({nv} vertices)", big)]
        rows = []
        for name, scene in scenes:
            key = name.split()[0]
            row = {"scene": name}
            for label, flags in (("plain", []), ("quantized", ["--quantize"]), ("meshopt", ["--meshopt"]),
                                 ("quantized+meshopt", ["--quantize", "--meshopt"]), ("compact", ["--compact=only"]),
                                 ("compact+meshopt", ["--compact=only", "--meshopt"])):
                r = export(a.csrbf, scene, os.path.join(tmp, f"{key}-{label}.glb"), *flags)
                row[label] = r["bytes"]
                row.setdefault("vertices", sum(o["vertices"] for o in r["objects"]))
            page = os.path.join(tmp, key + "-page")
            r = export(a.csrbf, scene, os.path.join(tmp, f"{key}-fallback.glb"), "--compact", html=page)
            row["target_bytes"] = r["compact"]["replaced_target_bytes"]
            row["extension_bytes"] = r["compact"]["compact_bytes"]
            row["targets_fps"] = page_fps(os.path.join(page, "index.html"), a.frames, "targets")
            row["shader_fps"] = page_fps(os.path.join(page, "index.html"), a.frames, "shader")
            rows.append(row)
            print(json.dumps(row), flush=True)
        print()
        print("| scene | vertices | morph targets | `--quantize` | `--meshopt` | both | `--compact=only` | "
              "`--compact=only --meshopt` | targets' bytes → extension's | page fps: targets / shader |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        for r in rows:
            ratio = r["target_bytes"] / r["extension_bytes"] if r["extension_bytes"] else float("nan")
            print(f"| {r['scene']} | {r['vertices']} | {r['plain']:,} | {r['quantized']:,} | {r['meshopt']:,} | "
                  f"{r['quantized+meshopt']:,} | {r['compact']:,} | {r['compact+meshopt']:,} | "
                  f"{r['target_bytes']:,} → {r['extension_bytes']:,} (1/{ratio:.0f}) | "
                  f"{r['targets_fps']:.0f} / {r['shader_fps']:.0f} |".replace(",", " "))
        if a.json:
            with open(a.json, "w") as out:
                json.dump(rows, out, indent=1)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
