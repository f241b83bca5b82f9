#!/usr/bin/python3
"""Writes examples/face.obj and examples/face.controls: a procedural head in the unit cube.

The paper's Figure 1 face (6158 vertices, 7024 polygons, 32 control vectors, R = 0.2) is not
distributed, so this is a stand-in of the same size: a head-shaped closed surface of 76 rings of 81
vertices plus two poles (6158 vertices, 6237 polygons) with a nose, brows, eye sockets, lips and a
chin, and 32 control vectors that make it smile and raise its brows, pinning the rest of the face.
Deterministic: no randomness. Run: /usr/bin/python3 scripts/make_face.py  (from the repository root)
"""
import math
import os

RINGS, AROUND = 76, 81


def bump(x, y, cx, cy, sx, sy):
    return math.exp(-(((x - cx) / sx) ** 2 + ((y - cy) / sy) ** 2))


def head_point(v, u):
    """v in (0, 1) from the crown (0) to under the chin (1); u in [0, 1) around (0.5 = the front)."""
    theta = math.pi * v
    phi = 2.0 * math.pi * u
    # An egg: wider at the cranium, narrower at the jaw.
    width = 0.36 * (1.0 - 0.12 * v)
    x = width * math.sin(theta) * math.sin(phi)
    y = 0.46 * math.cos(theta)
    z = -0.40 * math.sin(theta) * math.cos(phi)
    # Facial relief on the front (z > 0): coordinates of the front view.
    if z > 0.0:
        f = z / 0.40
        fx, fy = x, y
        relief = 0.0
        relief += 0.11 * bump(fx, fy, 0.0, -0.02, 0.045, 0.11)          # nose
        relief += 0.03 * bump(fx, fy, 0.0, 0.12, 0.22, 0.035)           # brow ridge
        relief -= 0.045 * bump(fx, fy, -0.11, 0.06, 0.06, 0.04)         # eye sockets
        relief -= 0.045 * bump(fx, fy, 0.11, 0.06, 0.06, 0.04)
        relief += 0.025 * bump(fx, fy, 0.0, -0.17, 0.08, 0.02)          # lips
        relief += 0.03 * bump(fx, fy, 0.0, -0.30, 0.08, 0.05)           # chin
        z += relief * f
    return (0.5 + x, 0.5 + y, 0.5 + z)


def main():
    here = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples")
    verts = [(0.5, 0.96, 0.5)]
    for r in range(RINGS):
        v = (r + 1) / (RINGS + 1)
        for a in range(AROUND):
            verts.append(head_point(v, a / AROUND))
    verts.append((0.5, 0.04 + 0.0, 0.5))
    faces = []
    for a in range(AROUND):  # crown fan
        faces.append((1, 2 + (a + 1) % AROUND, 2 + a))
    for r in range(RINGS - 1):
        base = 2 + r * AROUND
        for a in range(AROUND):
            b = (a + 1) % AROUND
            faces.append((base + a, base + b, base + AROUND + b, base + AROUND + a))
    last = 2 + (RINGS - 1) * AROUND
    bottom = len(verts)
    for a in range(AROUND):  # chin fan
        faces.append((last + a, last + (a + 1) % AROUND, bottom))
    with open(os.path.join(here, "face.obj"), "w") as f:
        f.write("# procedural head, scripts/make_face.py: %d vertices, %d polygons\n" % (len(verts), len(faces)))
        for p in verts:
            f.write("v %.6f %.6f %.6f\n" % p)
        for face in faces:
            f.write("f " + " ".join(str(i) for i in face) + "\n")

    # 32 control vectors on the front, found on the surface by (v, u).
    def at(v, u):
        return head_point(v, u)

    controls = []
    # smile: mouth corners up and out (4), upper/lower lip centre slightly (2)
    for side in (-1, 1):
        for dv in (0.0, 0.02):
            s = at(0.69 + dv, 0.5 + side * 0.07)
            controls.append((s, (s[0] + side * 0.02, s[1] + 0.035, s[2])))
    for v in (0.665, 0.715):
        s = at(v, 0.5)
        controls.append((s, (s[0], s[1] + 0.01, s[2])))
    # brows raised (8)
    for side in (-1, 1):
        for du in (0.04, 0.07, 0.1, 0.13):
            s = at(0.36, 0.5 + side * du)
            controls.append((s, (s[0], s[1] + 0.03, s[2])))
    # pinned points (18): nose, eyes, chin, cheeks, forehead
    pins = [(0.52, 0.5), (0.47, 0.5), (0.85, 0.5), (0.82, 0.46), (0.82, 0.54), (0.44, 0.43), (0.44, 0.57),
            (0.58, 0.38), (0.58, 0.62), (0.68, 0.36), (0.68, 0.64), (0.25, 0.5), (0.25, 0.4), (0.25, 0.6),
            (0.78, 0.4), (0.78, 0.6), (0.6, 0.5), (0.3, 0.5)]
    for v, u in pins:
        s = at(v, u)
        controls.append((s, s))
    assert len(controls) == 32, len(controls)
    with open(os.path.join(here, "face.controls"), "w") as f:
        f.write("# 32 control vectors for examples/face.obj (scripts/make_face.py); use R = 0.2\n")
        f.write("# sx sy sz dx dy dz: a smile and raised brows; 18 pinned points\n")
        for s, d in controls:
            f.write("%.6f %.6f %.6f %.6f %.6f %.6f\n" % (s + d))


if __name__ == "__main__":
    main()
