#!/usr/bin/python3
"""Writes examples/bunny.controls for examples/bunny.obj: bends the ears forward and pins the head.

Deterministic. Run: /usr/bin/python3 scripts/make_bunny_controls.py  (from the repository root).
Use with R = 2.5 (the bunny is about 10 units tall).
"""
import os

root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples")
verts = []
with open(os.path.join(root, "bunny.obj")) as f:
    for line in f:
        if line.startswith("v "):
            verts.append(tuple(float(t) for t in line.split()[1:4]))

tips = sorted(range(len(verts)), key=lambda i: -verts[i][1])[:40:4]  # 10 ear-tip vertices
pins = [i for i in range(len(verts)) if 5.6 < verts[i][1] < 6.4][::10]
with open(os.path.join(root, "bunny.controls"), "w") as f:
    f.write("# controls for examples/bunny.obj (scripts/make_bunny_controls.py); use R = 2.5\n")
    f.write("# sx sy sz dx dy dz\n# ear tips bend forward (+z) and down\n")
    for i in tips:
        x, y, z = verts[i]
        k = (y - 8.0) / 1.7
        f.write("%.6f %.6f %.6f %.6f %.6f %.6f\n" % (x, y, z, x, y - 0.4 * k, z + 1.2 * k))
    f.write("# the head stays where it is\n")
    for i in pins:
        x, y, z = verts[i]
        f.write("%.6f %.6f %.6f %.6f %.6f %.6f\n" % (x, y, z, x, y, z))
