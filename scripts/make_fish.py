#!/usr/bin/python3
"""Writes examples/fish.obj and examples/fish.controls: a procedural fish in the unit cube.

The paper's benchmark fish (975 vertices, 1119 polygons, 92 control vectors on the mouth, tail and
fin, R = 0.3) is not distributed, so this is a stand-in of the same size: a closed surface of 39
rings of 25 vertices plus two poles (977 vertices, 1000 polygons), and 92 control vectors that
swing the tail, open the mouth, bend the dorsal fin and pin the body. Deterministic: no randomness.
Run: /usr/bin/python3 scripts/make_fish.py  (from the repository root)
"""
import math
import os

RINGS, AROUND = 39, 25
X0, X1 = 0.05, 0.95  # nose and tail tip along x; the fish is centred at (0.5, 0.5, 0.5)


def half_axes(s):
    """Half-height (y) and half-width (z) of the cross-section at s in [0, 1] (nose to tail)."""
    body = math.sin(math.pi * min(s / 0.8, 1.0)) ** 0.7
    width = 0.11 * body + 0.008
    height = 0.16 * body
    if s > 0.72:  # the tail fin: thin and tall
        height = max(height, 0.02 + 0.2 * ((s - 0.72) / 0.28) ** 1.3)
        width = 0.008 + (width - 0.008) * max(0.0, 1.0 - (s - 0.72) / 0.12)
    return height, width


def ring_point(s, theta):
    h, w = half_axes(s)
    y = h * math.cos(theta)
    z = w * math.sin(theta)
    if 0.3 < s < 0.62:  # dorsal fin on top (theta near 0)
        bump = math.sin(math.pi * (s - 0.3) / 0.32)
        y += 0.09 * bump * max(0.0, math.cos(theta)) ** 16
    x = X0 + (X1 - X0) * s
    return (x, 0.5 + y, 0.5 + z)


def main():
    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples")
    verts = [(X0, 0.5, 0.5)]
    meta = [(0.0, 0.0)]
    for i in range(RINGS):
        s = (i + 1) / (RINGS + 1)
        for j in range(AROUND):
            theta = 2 * math.pi * j / AROUND
            verts.append(ring_point(s, theta))
            meta.append((s, theta))
    verts.append((X1, 0.5 + half_axes(1.0)[0] * 0.0, 0.5))
    meta.append((1.0, 0.0))
    tail = len(verts) - 1

    def vid(i, j):
        return 1 + i * AROUND + (j % AROUND)

    faces = []
    for j in range(AROUND):
        faces.append((0, vid(0, j + 1), vid(0, j)))
    for i in range(RINGS - 1):
        for j in range(AROUND):
            faces.append((vid(i, j), vid(i, j + 1), vid(i + 1, j + 1), vid(i + 1, j)))
    for j in range(AROUND):
        faces.append((tail, vid(RINGS - 1, j), vid(RINGS - 1, j + 1)))

    with open(os.path.join(root, "fish.obj"), "w") as f:
        f.write("# procedural fish for csrbf (scripts/make_fish.py): %d vertices, %d polygons, unit cube\n"
                % (len(verts), len(faces)))
        for v in verts:
            f.write("v %.6f %.6f %.6f\n" % v)
        for face in faces:
            f.write("f " + " ".join(str(k + 1) for k in face) + "\n")

    controls = []  # (vertex, dx, dy, dz, comment)
    # Tail: the last rings swing sideways (+z), more towards the tip. 30 controls.
    tail_ids = [vid(i, j) for i in range(RINGS - 6, RINGS) for j in range(0, AROUND, 5)]
    for k in tail_ids:
        s = meta[k][0]
        controls.append((k, 0.0, 0.0, 0.16 * ((s - 0.82) / 0.18) ** 2, "tail"))
    # Mouth: the lower half of the first two rings opens downwards. 12 controls.
    mouth_ids = [vid(i, j) for i in range(2) for j in range(10, 16)]
    for k in mouth_ids:
        controls.append((k, 0.0, -0.035, 0.0, "mouth"))
    # Dorsal fin: the top vertex of the fin rings bends sideways. 12 controls.
    fin_ids = [vid(i, 0) for i in range(12, 24)]
    for k in fin_ids:
        s = meta[k][0]
        controls.append((k, 0.0, 0.0, 0.05 * math.sin(math.pi * (s - 0.3) / 0.32), "fin"))
    # Anchors: the body keeps its shape. 38 controls with zero displacement.
    anchor_ids = []
    for i in (4, 8, 12, 17, 21, 25, 29):
        for j in range(1, AROUND, 4):
            anchor_ids.append(vid(i, j))
    used = set(tail_ids) | set(mouth_ids) | set(fin_ids)
    anchor_ids = [k for k in anchor_ids if k not in used][:92 - len(controls)]
    for k in anchor_ids:
        controls.append((k, 0.0, 0.0, 0.0, "anchor"))
    assert len(controls) == 92, len(controls)
    assert len({c[0] for c in controls}) == 92

    with open(os.path.join(root, "fish.controls"), "w") as f:
        f.write("# 92 control vectors for examples/fish.obj (scripts/make_fish.py); use R = 0.3\n")
        f.write("# sx sy sz dx dy dz\n")
        last = None
        for k, dx, dy, dz, what in controls:
            if what != last:
                f.write("# %s\n" % what)
                last = what
            x, y, z = verts[k]
            f.write("%.6f %.6f %.6f %.6f %.6f %.6f\n" % (x, y, z, x + dx, y + dy, z + dz))


if __name__ == "__main__":
    main()
